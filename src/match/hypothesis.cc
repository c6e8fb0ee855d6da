// SPDX-License-Identifier: MIT
#include "match/hypothesis.h"

#include <Eigen/Geometry>
#include <cmath>

#include "util/angles.h"

namespace horizonreg {

std::optional<PaperHypothesis> PaperHypothesisFromPairs(const ImagePoint& p1, const ImagePoint& p2,
                                                         const HorizonPoint& h1, const HorizonPoint& h2, double cx,
                                                         double cy) {
  const double x1 = p1.x - cx, x2 = p2.x - cx;
  // Image y grows downwards; the paper's y grows upwards with elevation.
  const double y1 = cy - p1.y, y2 = cy - p2.y;
  const double dx = x2 - x1, dy = y2 - y1;
  const double dalpha = AngDiffDeg(h2.azimuth_deg, h1.azimuth_deg);
  if (!(dx > 0.0) || !(dalpha > 0.0) || std::abs(x2) < 1e-9) return std::nullopt;
  const double da = DegToRad(dalpha);
  PaperHypothesis h;
  // Eq. (5): alpha_c = alpha_2 - arctan(sin(da) / (cos(da) - x1 / x2)), the
  // arctangent taken on the branch where x2 and tan(alpha_2 - alpha_c) agree in sign.
  double beta2 = std::atan2(std::sin(da), std::cos(da) - x1 / x2);
  if (beta2 > kPi / 2) beta2 -= kPi;
  if (beta2 < -kPi / 2) beta2 += kPi;
  h.azimuth_deg = WrapAzimuthDeg(h2.azimuth_deg - RadToDeg(beta2));
  // Eq. (8): C_x = dx / (2 cos((alpha_1 + alpha_2 - 2 alpha_c) / 2) sin(da / 2)), pixels per radian.
  const double mean_offset = DegToRad(0.5 * (AngDiffDeg(h1.azimuth_deg, h.azimuth_deg) +
                                             AngDiffDeg(h2.azimuth_deg, h.azimuth_deg)));
  h.cx_px_per_deg = DegToRad(dx / (2.0 * std::cos(mean_offset) * std::sin(da / 2.0)));
  // Eq. (9): C_y = dy / d(theta); eq. (6): theta_c = (theta_1 y2 - theta_2 y1) / dy.
  const double dtheta = h2.elevation_deg - h1.elevation_deg;
  if (std::abs(dy) > 1e-9) {
    h.cy_px_per_deg = dy / dtheta;
    h.pitch_deg = (h1.elevation_deg * y2 - h2.elevation_deg * y1) / dy;
  } else {  // same image height: C_y is undetermined, take square pixels
    h.cy_px_per_deg = h.cx_px_per_deg;
    h.pitch_deg = h1.elevation_deg - y1 / h.cy_px_per_deg;
  }
  if (!std::isfinite(h.pitch_deg) || !std::isfinite(h.cy_px_per_deg)) return std::nullopt;
  return h;
}

namespace {

Eigen::Vector3d EnuOf(const HorizonPoint& h) {
  const double az = DegToRad(h.azimuth_deg), el = DegToRad(h.elevation_deg);
  return {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
}

// Cosine of the angle between the rays through two pixels (offsets from the
// principal point) for focal length f.
double RayCosine(const Eigen::Vector2d& u1, const Eigen::Vector2d& u2, double f) {
  const double f2 = f * f;
  return (u1.dot(u2) + f2) / std::sqrt((u1.squaredNorm() + f2) * (u2.squaredNorm() + f2));
}

// Rotation R with R a_i ~ b_i for two pairs of unit vectors (triad on the
// bisectors, which splits any mismatch of the two angles evenly).
Eigen::Matrix3d TwoVectorRotation(const Eigen::Vector3d& a1, const Eigen::Vector3d& a2, const Eigen::Vector3d& b1,
                                  const Eigen::Vector3d& b2) {
  auto frame = [](const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
    const Eigen::Vector3d s = (v1 + v2).normalized(), d = (v1 - v2).normalized();
    Eigen::Matrix3d m;
    m.col(0) = s;
    m.col(1) = d;
    m.col(2) = s.cross(d);
    return m;
  };
  return frame(b1, b2) * frame(a1, a2).transpose();
}

}  // namespace

std::vector<PoseHypothesis> TwoPointPoses(const ImagePoint& p1, const ImagePoint& p2, const HorizonPoint& h1,
                                          const HorizonPoint& h2, double cx, double cy, double min_focal_px,
                                          double max_focal_px) {
  std::vector<PoseHypothesis> out;
  const Eigen::Vector3d d1 = EnuOf(h1), d2 = EnuOf(h2);
  const double target = d1.dot(d2);
  const Eigen::Vector2d u1(p1.x - cx, p1.y - cy), u2(p2.x - cx, p2.y - cy);
  if ((u1 - u2).norm() < 1e-9 || target > 1.0 - 1e-12 || !(min_focal_px > 0 && max_focal_px > min_focal_px))
    return out;
  constexpr int kGrid = 12;
  const double ratio = std::pow(max_focal_px / min_focal_px, 1.0 / kGrid);
  double f0 = min_focal_px, g0 = RayCosine(u1, u2, f0) - target;
  for (int i = 1; i <= kGrid; ++i) {
    const double f1 = i == kGrid ? max_focal_px : f0 * ratio, g1 = RayCosine(u1, u2, f1) - target;
    if ((g0 <= 0) != (g1 <= 0)) {
      double lo = f0, hi = f1;
      const bool rising = g0 <= 0;
      for (int k = 0; k < 50 && hi - lo > 1e-7 * hi; ++k) {
        const double mid = 0.5 * (lo + hi);
        ((RayCosine(u1, u2, mid) - target <= 0) == rising ? lo : hi) = mid;
      }
      const double f = 0.5 * (lo + hi);
      const Eigen::Vector3d r1 = Eigen::Vector3d(u1.x() / f, u1.y() / f, 1.0).normalized();
      const Eigen::Vector3d r2 = Eigen::Vector3d(u2.x() / f, u2.y() / f, 1.0).normalized();
      out.push_back({PoseFromCamFromEnu(TwoVectorRotation(d1, d2, r1, r2)), f});  // maps d_i onto r_i
    }
    f0 = f1;
    g0 = g1;
  }
  return out;
}

}  // namespace horizonreg
