// SPDX-License-Identifier: MIT
// Internal to the match module: what a pose is fitted to. The DEM horizon
// as a function of azimuth with its error model, the skyline columns in lens
// corrected coordinates, the residual of one column, and the one-sided
// robust loss that knows the DEM's limits. Not a public header.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <type_traits>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/register.h"
#include "util/angles.h"

namespace horizonreg::match_detail {

inline double ScalarOf(double v) { return v; }
template <typename J>
double ScalarOf(const J& v) {
  return v.a;
}

// The DEM horizon's elevation angle (radians) at any azimuth (radians),
// linear between bin centres, periodic; also for ceres::Jet. Per bin it also
// holds the DEM's error model (DemErrorModel): the one-sided flattening (a
// grid cuts sharp peaks and ridges: the true horizon lies above the DEM's)
// and the symmetric uncertainty from the observer's position and height.
class HorizonLookup {
 public:
  HorizonLookup(const HorizonProfile& p, const DemErrorModel& model);
  template <typename T>
  T operator()(const T& azimuth_rad) const {
    const double u = ScalarOf(azimuth_rad) / step_rad_;
    const double fl = std::floor(u);
    const int i = Wrap(static_cast<long long>(fl));
    const T t = azimuth_rad / step_rad_ - fl;
    return el_[i] + (el_[i + 1] - el_[i]) * t;
  }
  double Slope(double azimuth_rad) const {  // d(elevation)/d(azimuth), dimensionless
    const int i = Bin(azimuth_rad);
    return (el_[i + 1] - el_[i]) / step_rad_;
  }
  // Of the nearer of the two bins around the azimuth:
  double DistanceM(double azimuth_rad) const { return distance_m_[Bin(azimuth_rad)]; }
  double FlatteningRad(double azimuth_rad) const { return flattening_rad_[Bin(azimuth_rad)]; }
  double PositionSigmaRad(double azimuth_rad) const { return position_rad_[Bin(azimuth_rad)]; }
  double PostSpacingM(double azimuth_rad) const { return spacing_m_[Bin(azimuth_rad)]; }
  double step_rad() const { return step_rad_; }
  const HorizonProfile& profile() const { return *profile_; }

 private:
  int Wrap(long long i) const { return static_cast<int>(((i % n_) + n_) % n_); }
  int Bin(double azimuth_rad) const { return Wrap(static_cast<long long>(std::floor(azimuth_rad / step_rad_))); }
  const HorizonProfile* profile_;
  int n_;
  double step_rad_;
  std::vector<double> el_;              // n + 1 (periodic)
  std::vector<double> distance_m_;      // per bin pair (i, i + 1): the nearer
  std::vector<double> flattening_rad_;  // per bin pair: the larger
  std::vector<double> position_rad_;    // per bin pair: the larger
  std::vector<double> spacing_m_;       // per bin pair: the larger (NaN when unknown)
};

// One skyline point. (u, v): its offset from the principal point in pixels,
// lens distortion removed when the lens is known (then u = fx x_n, v = fx
// y_n for the normalised undistorted coordinates), as observed otherwise
// (radial distortion k1 about the principal point may then be fitted).
struct Column {
  double u = 0.0, v = 0.0;
  double x_px = 0.0;         // image column (for statistics by column)
  double slope_weight = 1.0;  // 1 / sqrt(1 + slope^2): vertical to perpendicular distance
  double noise_px = 1.0;      // symmetric 1-sigma of the residual (extraction + observer position), pixels
  double flattening_px = 0.0;  // expected one-sided excess of the skyline over the DEM horizon, pixels
};

// A camera pose and its intrinsics as fitted: yaw, pitch, roll (radians),
// focal length (pixels), radial distortion k1 (on normalised coordinates).
struct Pose4 {
  double yaw = 0.0, pitch = 0.0, roll = 0.0;
  double f = 1.0;
  double k1 = 0.0;
  CameraPose ToPose() const {
    return {WrapAzimuthDeg(RadToDeg(yaw)), RadToDeg(pitch), RadToDeg(std::remainder(roll, 2.0 * kPi))};
  }
  static Pose4 From(const CameraPose& p, double f, double k1 = 0.0) {
    return {DegToRad(p.azimuth_deg), DegToRad(p.pitch_deg), DegToRad(p.roll_deg), f, k1};
  }
};

// Normalised undistorted coordinates of a column under focal f and radial
// k1 (fixed-point inversion of x_d = x (1 + k1 r^2); converges for
// |k1| r^2 < 0.3, far beyond any lens this is fitted to).
template <typename T>
void Undistorted(const Column& c, const T& f, const T& k1, T& xn, T& yn, bool distorted = true) {
  const T xd = c.u / f, yd = c.v / f;
  xn = xd, yn = yd;
  if (!distorted || (ScalarOf(k1) == 0.0 && std::is_same_v<T, double>)) return;
  for (int it = 0; it < 6; ++it) {
    const T s = 1.0 + k1 * (xn * xn + yn * yn);
    xn = xd / s, yn = yd / s;
  }
}

// Residual of one column, pixels (perpendicular to the projected
// silhouette): the DEM horizon's elevation minus the elevation of the ray
// through the point, scaled to pixels. Positive when the skyline point lies
// *below* the DEM horizon; negative when above it (where a coarse DEM's cut
// peaks leave it).
template <typename T>
T ColumnResidual(const Eigen::Matrix<T, 3, 3>& cam_from_enu, const T& f, const T& k1, const Column& c,
                 const HorizonLookup& horizon, bool distorted = true) {
  using std::atan2;
  using std::sqrt;
  T xn, yn;
  Undistorted(c, f, k1, xn, yn, distorted);
  const Eigen::Matrix<T, 3, 1> d = cam_from_enu.transpose() * Eigen::Matrix<T, 3, 1>(xn, yn, T(1.0));
  const T az = atan2(d.x(), d.y());
  const T el = atan2(d.z(), sqrt(d.x() * d.x() + d.y() * d.y()));
  return (horizon(az) - el) * f * (1.0 + yn * yn) * sqrt(1.0 + xn * xn) * c.slope_weight;
}

// The one-sided loss of a residual r (pixels, ColumnResidual's sign) for a
// column: with rho = -r (positive: the skyline lies above the DEM horizon),
//   rho <= kappa:  rho^2 / (2 s^2)                (Gaussian noise, s = noise_px)
//   rho > kappa:   kappa (rho - kappa / 2) / s^2  (an exponential excess of
//                                                 mean u = flattening_px: a
//                                                 coarse DEM cuts peaks)
// with kappa = s^2 / u (the slopes meet): the skyline may stand above the
// DEM horizon by about u, never below it. With u -> 0 it is a Gaussian.
struct ColumnLoss {
  double s = 1.0, kappa = INFINITY;
  ColumnLoss(double noise_px, double flattening_px)
      : s(noise_px), kappa(flattening_px > 0.0 ? noise_px * noise_px / flattening_px : INFINITY) {}
  explicit ColumnLoss(const Column& c) : ColumnLoss(c.noise_px, c.flattening_px) {}
  // 2 x the negative log-likelihood (0 at rho = 0): the squared normalised residual.
  double Chi2(double r) const {
    const double rho = -r;
    if (rho <= kappa) return rho * rho / (s * s);
    return kappa * (2.0 * rho - kappa) / (s * s);
  }
  // IRLS weight (Huber's) for r: 1 / s^2 inside, kappa / (rho s^2) on the excess side.
  double Weight(double r) const {
    const double rho = -r;
    return (rho <= kappa ? 1.0 : kappa / rho) / (s * s);
  }
  // Largest excess rho inside the inlier gate Chi2 <= gate2.
  double MaxRho(double gate2) const {
    const double g = std::sqrt(gate2) * s;
    return g <= kappa ? g : 0.5 * (gate2 * s * s / kappa + kappa);
  }
  // The expected Chi2 of a column that follows the model (1 on the Gaussian
  // side, 2 + kappa^2 / s^2 on the exponential side, by their masses).
  double ExpectedChi2() const;
  // log of the normalising integral of exp(-Chi2 / 2) (pixels).
  double LogNorm() const;
  // 2 log(Z / Z_sigma), Z the normalising integral (approximated within 3%
  // by s sqrt(pi / 2) + sqrt(s^2 pi / 2 + u^2)) and Z_sigma = sigma sqrt(2 pi)
  // that of the bare pixel noise: what a column's wider tolerance costs in a
  // likelihood comparison (a model that allows more explains less).
  double WidthCost(double sigma) const {
    constexpr double kHalfPi = 1.5707963267948966, kSqrtHalfPi = 1.2533141373155003, kSqrtTwoPi = 2.5066282746310002;
    const double u = std::isfinite(kappa) ? s * s / kappa : 0.0;
    return 2.0 * std::log((s * kSqrtHalfPi + std::sqrt(s * s * kHalfPi + u * u)) / (sigma * kSqrtTwoPi));
  }
};

}  // namespace horizonreg::match_detail
