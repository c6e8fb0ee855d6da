// SPDX-License-Identifier: MIT
#include "match/register.h"

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <ceres/manifold.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <thread>

#include "geo/geodesy.h"
#include "match/extrema.h"
#include "match/hypothesis.h"
#include "util/angles.h"
#include "util/errors.h"
#include "util/fast_math.h"

namespace horizonreg {

void SensorPrior::Check() const {
  auto fail = [](const char* field, double v, const char* rule) {
    std::ostringstream m;
    m << "SensorPrior::" << field << " = " << v << "; violated: " << rule;
    throw InvalidArgument(m.str());
  };
  if (compass_deg && !std::isfinite(*compass_deg)) fail("compass_deg", *compass_deg, "finite");
  if (pitch_deg && !(std::abs(*pitch_deg) <= 90.0)) fail("pitch_deg", *pitch_deg, "-90 <= pitch <= 90");
  if (roll_deg && !(std::abs(*roll_deg) <= 180.0)) fail("roll_deg", *roll_deg, "-180 <= roll <= 180");
  if (!(compass_sigma_deg > 0.0 && compass_sigma_deg < 180.0))
    fail("compass_sigma_deg", compass_sigma_deg, "0 < sigma < 180");
  if (!(inclinometer_sigma_deg > 0.0 && inclinometer_sigma_deg < 90.0))
    fail("inclinometer_sigma_deg", inclinometer_sigma_deg, "0 < sigma < 90");
  if (!(gate_sigmas > 0.0 && std::isfinite(gate_sigmas))) fail("gate_sigmas", gate_sigmas, "0 < gate_sigmas < inf");
}

void RegistrationOptions::Check() const {
  auto fail = [](const char* field, double v, const char* rule) {
    std::ostringstream m;
    m << "RegistrationOptions::" << field << " = " << v << "; violated: " << rule;
    throw InvalidArgument(m.str());
  };
  if (!(min_hfov_deg > 0.0 && min_hfov_deg < 170.0)) fail("min_hfov_deg", min_hfov_deg, "0 < min_hfov_deg < 170");
  if (!(max_hfov_deg >= min_hfov_deg && max_hfov_deg < 170.0))
    fail("max_hfov_deg", max_hfov_deg, "min_hfov_deg <= max_hfov_deg < 170");
  if (!(max_abs_roll_deg >= 0.0 && max_abs_roll_deg <= 180.0))
    fail("max_abs_roll_deg", max_abs_roll_deg, "0 <= max_abs_roll_deg <= 180");
  if (image_extrema < 2) fail("image_extrema", image_extrema, "image_extrema >= 2");
  if (horizon_extrema < 2) fail("horizon_extrema", horizon_extrema, "horizon_extrema >= 2");
  if (!(min_image_prominence_px >= 0.0)) fail("min_image_prominence_px", min_image_prominence_px, ">= 0");
  if (!(min_horizon_prominence_deg >= 0.0)) fail("min_horizon_prominence_deg", min_horizon_prominence_deg, ">= 0");
  if (coarse_columns < 8) fail("coarse_columns", coarse_columns, "coarse_columns >= 8");
  if (refine_columns < 8) fail("refine_columns", refine_columns, "refine_columns >= 8");
  if (candidates < 2) fail("candidates", candidates, "candidates >= 2");
  if (quick_columns < 8) fail("quick_columns", quick_columns, "quick_columns >= 8");
  if (refined_candidates < 2) fail("refined_candidates", refined_candidates, "refined_candidates >= 2");
  if (num_threads < 1) fail("num_threads", num_threads, "num_threads >= 1");
  if (!(inlier_px > 0.0)) fail("inlier_px", inlier_px, "inlier_px > 0");
  if (!(min_visible_fraction >= 0.0 && min_visible_fraction <= 1.0))
    fail("min_visible_fraction", min_visible_fraction, "0 <= f <= 1");
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0))
    fail("min_inlier_fraction", min_inlier_fraction, "0 <= f <= 1");
  if (!(max_rms_px > 0.0)) fail("max_rms_px", max_rms_px, "max_rms_px > 0");
  if (!(min_ambiguity_ratio >= 1.0)) fail("min_ambiguity_ratio", min_ambiguity_ratio, "min_ambiguity_ratio >= 1");
  prior.Check();
}

double ToleranceScale(int width) { return std::max(1.0, width / 1000.0); }

CameraIntrinsics Registration::Intrinsics(int width, int height) const {
  CameraIntrinsics k = CameraIntrinsics::FromHfov(width, height, 60.0);
  k.focal_px = focal_px;
  return k;
}

namespace {

double ScalarOf(double v) { return v; }
template <typename T, int N>
double ScalarOf(const ceres::Jet<T, N>& v) {
  return v.a;
}

// The DEM horizon's elevation angle (radians) at any azimuth (radians),
// linear between bin centres, periodic; also for ceres::Jet.
class HorizonLookup {
 public:
  explicit HorizonLookup(const HorizonProfile& p)
      : n_(p.size()),
        step_rad_(DegToRad(p.azimuth_step_deg)),
        el_(static_cast<size_t>(n_) + 1),
        distance_m_(p.distance_m) {
    for (int i = 0; i < n_; ++i) el_[i] = DegToRad(p.elevation_deg[i]);
    el_[n_] = el_[0];
  }
  template <typename T>
  T operator()(const T& azimuth_rad) const {
    const double u = ScalarOf(azimuth_rad) / step_rad_;
    const double fl = std::floor(u);
    const int i = static_cast<int>(((static_cast<long long>(fl) % n_) + n_) % n_);
    const T t = azimuth_rad / step_rad_ - fl;
    return el_[i] + (el_[i + 1] - el_[i]) * t;
  }
  double Slope(double azimuth_rad) const {  // d(elevation)/d(azimuth), dimensionless
    const int i = Bin(azimuth_rad);
    return (el_[i + 1] - el_[i]) / step_rad_;
  }
  double DistanceM(double azimuth_rad) const {  // of the nearer of the two bins around the azimuth
    const int i = Bin(azimuth_rad);
    return std::min(distance_m_[i], distance_m_[(i + 1) % n_]);
  }

 private:
  int Bin(double azimuth_rad) const {
    const double u = azimuth_rad / step_rad_;
    return static_cast<int>(((static_cast<long long>(std::floor(u)) % n_) + n_) % n_);
  }
  int n_;
  double step_rad_;
  std::vector<double> el_;
  std::vector<double> distance_m_;
};

// Near terrain is where the DEM and the world differ most: a post's few
// metres of error, the GPS error and the eye height move a ridge 100 m away
// by degrees. Its columns count less in the fit (weight d^2 / (d^2 + d0^2)).
constexpr double kNearFieldM = 400.0;

struct Column {
  double x = 0.0, y = 0.0;  // skyline point
  double weight = 1.0;      // 1 / sqrt(1 + slope^2): vertical to perpendicular distance
  double fit_weight = 1.0;  // weight times the near-field down-weighting, for the least squares
};

// Residual of one column, pixels: the DEM horizon's elevation minus the
// elevation of the ray through (x, y), scaled to pixels across the silhouette.
template <typename T>
T ColumnResidual(const Eigen::Matrix<T, 3, 3>& cam_from_enu, const T& f, const Column& c, double weight, double cx,
                 double cy, const HorizonLookup& horizon) {
  using std::atan2;
  using std::sqrt;
  const T xn = (c.x - cx) / f, yn = (c.y - cy) / f;
  const Eigen::Matrix<T, 3, 1> ray(xn, yn, T(1.0));
  const Eigen::Matrix<T, 3, 1> d = cam_from_enu.transpose() * ray;
  const T az = atan2(d.x(), d.y());
  const T el = atan2(d.z(), sqrt(d.x() * d.x() + d.y() * d.y()));
  return (horizon(az) - el) * f * (1.0 + yn * yn) * sqrt(1.0 + xn * xn) * weight;
}

struct Pose4 {
  double yaw = 0.0, pitch = 0.0, roll = 0.0;  // radians
  double f = 1.0;                             // pixels
  CameraPose ToPose() const {
    return {WrapAzimuthDeg(RadToDeg(yaw)), RadToDeg(pitch), RadToDeg(std::remainder(roll, 2.0 * kPi))};
  }
  static Pose4 From(const CameraPose& p, double f) {
    return {DegToRad(p.azimuth_deg), DegToRad(p.pitch_deg), DegToRad(p.roll_deg), f};
  }
};

class Scorer {
 public:
  Scorer(const HorizonLookup& horizon, double cx, double cy, double tau)
      : horizon_(horizon), cx_(cx), cy_(cy), tau2_(tau * tau) {}
  double Residual(const Eigen::Matrix3d& m, double f, const Column& c) const {
    return ColumnResidual<double>(m, f, c, c.weight, cx_, cy_, horizon_);
  }
  // Mean truncated squared residual; stops early once above `bound`.
  // ColumnResidual with the fast arctangent (|error| < 2e-7 rad), for scoring.
  double FastResidual(const Eigen::Matrix3d& m, double f, const Column& c) const {
    const double xn = (c.x - cx_) / f, yn = (c.y - cy_) / f;
    const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
    const double h = std::sqrt(d.x() * d.x() + d.y() * d.y());
    const double az = FastAtan2(d.x(), d.y()), el = FastAtan2(d.z(), h);
    return (horizon_(az) - el) * f * (1.0 + yn * yn) * std::sqrt(1.0 + xn * xn) * c.weight;
  }
  double Cost(const Pose4& p, const std::vector<Column>& cols, double bound = INFINITY) const {
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    const double limit = bound * cols.size();
    double sum = 0.0;
    for (const Column& c : cols) {
      const double r = FastResidual(m, p.f, c);
      sum += std::min(r * r, tau2_);
      if (sum > limit) return INFINITY;
    }
    return sum / cols.size();
  }
  double InlierFraction(const Pose4& p, const std::vector<Column>& cols) const {
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    int n = 0;
    for (const Column& c : cols) {
      const double r = FastResidual(m, p.f, c);
      n += r * r < tau2_;
    }
    return cols.empty() ? 0.0 : static_cast<double>(n) / cols.size();
  }
  // Column weights for a pose: the slope of the projected silhouette.
  void Reweight(const Pose4& p, std::vector<Column>& cols) const {
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    for (Column& c : cols) {
      const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d((c.x - cx_) / p.f, (c.y - cy_) / p.f, 1.0);
      const double az = std::atan2(d.x(), d.y());
      const double s = horizon_.Slope(az) / std::max(0.05, std::hypot(d.x(), d.y()) / d.norm());
      c.weight = 1.0 / std::sqrt(1.0 + s * s);
      const double dist = horizon_.DistanceM(az);
      c.fit_weight = c.weight * dist * dist / (dist * dist + kNearFieldM * kNearFieldM);
    }
  }
  const HorizonLookup& horizon() const { return horizon_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double tau2() const { return tau2_; }

 private:
  const HorizonLookup& horizon_;
  double cx_, cy_, tau2_;
};

// Calls fn(i, t) for every i in [0, n): item i on worker t = i mod W, with
// W = min(n, max_workers) threads (the caller's among them); waits for all.
template <typename Fn>
void ParallelFor(size_t n, int max_workers, Fn fn) {
  const int workers = static_cast<int>(std::clamp<size_t>(n, 1, max_workers));
  auto work = [&](int t) {
    for (size_t i = t; i < n; i += workers) fn(i, t);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < workers; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& th : pool) th.join();
}

std::vector<Column> VisibleColumns(const Skyline& skyline) {
  std::vector<Column> all;
  for (int i = 0; i < skyline.width; ++i)
    if (std::isfinite(skyline.y[i])) all.push_back({i + 0.5, skyline.y[i], 1.0});
  return all;
}

std::vector<Column> Subsample(const std::vector<Column>& all, int count) {
  if (static_cast<int>(all.size()) <= count) return all;
  std::vector<Column> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) out.push_back(all[(static_cast<size_t>(i) * all.size() + all.size() / 2) / count]);
  return out;
}

// All columns in one residual block (the rotation is built once per
// evaluation); residual i is the column's distance times sqrt(w_i), the
// iteratively reweighted Cauchy weight.
struct AllColumnsCost {
  const std::vector<Column>* cols;
  const std::vector<double>* sqrt_w;
  double cx, cy;
  const HorizonLookup* horizon;
  template <typename T>
  bool operator()(T const* const* params, T* residuals) const {
    const T* p = params[0];
    const Eigen::Matrix<T, 3, 3> m = CamFromEnuRad(p[0], p[1], p[2]);
    for (size_t i = 0; i < cols->size(); ++i) {
      const Column& c = (*cols)[i];
      residuals[i] = ColumnResidual<T>(m, p[3], c, c.fit_weight * (*sqrt_w)[i], cx, cy, *horizon);
    }
    return true;
  }
};

struct Refined {
  Pose4 pose;
  double sigma[4] = {NAN, NAN, NAN, NAN};
};

// Robust nonlinear least squares of yaw, pitch, roll and focal length:
// Levenberg-Marquardt (Ceres) inside iteratively reweighted least squares
// with the Cauchy loss of scale tau / 3.
Refined RefineLeastSquares(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start, double tau,
                           int rounds, bool want_covariance, double effective_fraction, bool fix_focal = false) {
  double p[4] = {start.yaw, start.pitch, start.roll, start.f};
  const double c2 = std::pow(tau / 3.0, 2);
  std::vector<double> sqrt_w(cols.size(), 1.0);
  auto reweight = [&] {
    const Eigen::Matrix3d m = CamFromEnuRad(p[0], p[1], p[2]);
    for (size_t i = 0; i < cols.size(); ++i) {
      const double r =
          ColumnResidual<double>(m, p[3], cols[i], cols[i].fit_weight, scorer.cx(), scorer.cy(), scorer.horizon());
      sqrt_w[i] = 1.0 / std::sqrt(1.0 + r * r / c2);
    }
  };
  auto* cost = new ceres::DynamicAutoDiffCostFunction<AllColumnsCost, 4>(
      new AllColumnsCost{&cols, &sqrt_w, scorer.cx(), scorer.cy(), &scorer.horizon()});
  cost->AddParameterBlock(4);
  cost->SetNumResiduals(static_cast<int>(cols.size()));
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, p);
  if (fix_focal) {
    problem.SetManifold(p, new ceres::SubsetManifold(4, {3}));
  } else {
    problem.SetParameterLowerBound(p, 3, 0.2 * start.f);
    problem.SetParameterUpperBound(p, 3, 5.0 * start.f);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 10;
  so.function_tolerance = 1e-8;
  so.logging_type = ceres::SILENT;
  so.num_threads = 1;
  for (int round = 0; round < rounds; ++round) {
    reweight();
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
  }
  Refined r;
  r.pose = {p[0], p[1], p[2], p[3]};
  if (!want_covariance) return r;
  // Residual variance from the inlier columns.
  const Eigen::Matrix3d m = CamFromEnuRad(p[0], p[1], p[2]);
  double ss = 0.0, sw = 0.0;
  int n = 0;
  for (size_t i = 0; i < cols.size(); ++i) {
    const double res =
        ColumnResidual<double>(m, p[3], cols[i], cols[i].fit_weight, scorer.cx(), scorer.cy(), scorer.horizon());
    if (std::abs(res) < tau) {
      ss += res * res * sqrt_w[i] * sqrt_w[i];
      sw += sqrt_w[i] * sqrt_w[i];
      ++n;
    }
  }
  if (n <= 4 || !(sw > 4.0)) return r;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{p, p}};
  if (!covariance.Compute(blocks, &problem)) return r;
  double cov[16];
  covariance.GetCovarianceBlock(p, p, cov);
  // Neighbouring columns share DEM bins and skyline pixels: count only the
  // independent ones (effective_fraction of the columns).
  const double variance = ss / (sw - 4.0) / std::clamp(effective_fraction, 1e-3, 1.0);
  for (int i = 0; i < 4; ++i) r.sigma[i] = std::sqrt(std::max(0.0, cov[i * 5] * variance));
  return r;
}

// Paper eq. (11)-(14): closest-point differences between the skyline and the
// projected DEM silhouette, straight-line fits of their horizontal and
// vertical components, corrections of azimuth, pitch and C_x = C_y (square
// pixels); the vertical fit also takes a slope across the image (roll).
struct PaperCorrection {
  Pose4 pose;
  double ex_px = NAN, ey_px = NAN;
};

PaperCorrection CorrectLinear(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start, int width,
                              double tau, const HorizonProfile& profile) {
  PaperCorrection out{start};
  for (int iter = 0; iter < 2; ++iter) {
    const Pose4& p = out.pose;
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    CameraIntrinsics k = CameraIntrinsics::FromHfov(width, 2 * static_cast<int>(scorer.cy()), 60.0);
    k.focal_px = p.f;
    k.cx = scorer.cx();
    k.cy = scorer.cy();
    // DEM silhouette polyline in the image, bins within the field of view.
    const double half = std::atan(0.6 * width / p.f) + 0.02;
    std::vector<Eigen::Vector2d> poly;
    const int n = profile.size();
    const double yaw_deg = RadToDeg(p.yaw);
    const int span = static_cast<int>(std::ceil(RadToDeg(half) / profile.azimuth_step_deg)) + 1;
    const int centre = static_cast<int>(std::lround(WrapAzimuthDeg(yaw_deg) / profile.azimuth_step_deg));
    for (int j = centre - span; j <= centre + span; ++j) {
      const int b = ((j % n) + n) % n;
      if (auto px = ProjectAzEl(m, k, j * profile.azimuth_step_deg, profile.elevation_deg[b])) poly.push_back(*px);
    }
    if (poly.size() < 2) return out;
    // Closest points.
    std::vector<double> xs, dxs, ys, dys;
    for (const Column& c : cols) {
      double best = INFINITY;
      Eigen::Vector2d q;
      const Eigen::Vector2d s(c.x, c.y);
      for (size_t i = 0; i + 1 < poly.size(); ++i) {
        const Eigen::Vector2d a = poly[i], e = poly[i + 1];
        if (std::max(a.x(), e.x()) < c.x - 3 * tau || std::min(a.x(), e.x()) > c.x + 3 * tau) continue;
        const Eigen::Vector2d ab = e - a;
        const double t = std::clamp((s - a).dot(ab) / std::max(1e-12, ab.squaredNorm()), 0.0, 1.0);
        const Eigen::Vector2d cand = a + t * ab;
        const double d2 = (cand - s).squaredNorm();
        if (d2 < best) {
          best = d2;
          q = cand;
        }
      }
      if (!(best < 9 * tau * tau)) continue;
      xs.push_back(c.x - scorer.cx());
      ys.push_back(scorer.cy() - c.y);
      dxs.push_back(q.x() - c.x);
      dys.push_back(c.y - q.y());  // up positive
    }
    const int count = static_cast<int>(xs.size());
    if (count < 8) return out;
    double sx2 = 0, sy2 = 0;
    for (int i = 0; i < count; ++i) {
      sx2 += dxs[i] * dxs[i];
      sy2 += dys[i] * dys[i];
    }
    out.ex_px = std::sqrt(sx2 / count);  // eq. (13)
    out.ey_px = std::sqrt(sy2 / count);  // eq. (14)
    // Eq. (11): dx = a + b x; eq. (12): dy = c + e y (+ g x for roll).
    Eigen::MatrixXd ax(count, 2), ay(count, 3);
    Eigen::VectorXd bx(count), by(count);
    for (int i = 0; i < count; ++i) {
      ax.row(i) << 1.0, xs[i];
      ay.row(i) << 1.0, ys[i], xs[i];
      bx(i) = dxs[i];
      by(i) = dys[i];
    }
    const Eigen::Vector2d lx = ax.colPivHouseholderQr().solve(bx);
    const Eigen::Vector3d ly = ay.colPivHouseholderQr().solve(by);
    Pose4 next = p;
    // A DEM point drawn dx to the right of its image point: the camera looks
    // dx / f radians too far left. Scale: the DEM spread is (1 + b) too wide.
    next.yaw += lx(0) / p.f;
    next.pitch -= ly(0) / p.f;
    const double scale = 1.0 + 0.5 * (lx(1) + ly(1));
    if (scale > 0.5 && scale < 2.0) next.f = p.f / scale;
    next.roll += std::atan(ly(2));
    if (!std::isfinite(next.yaw + next.pitch + next.f + next.roll)) return out;
    out.pose = next;
  }
  return out;
}

double PriorPenalty(const SensorPrior& prior, const CameraPose& pose) {
  double chi2 = 0.0;
  if (prior.compass_deg)
    chi2 += std::pow(AngDiffDeg(pose.azimuth_deg, *prior.compass_deg) / prior.compass_sigma_deg, 2);
  if (prior.pitch_deg) chi2 += std::pow((pose.pitch_deg - *prior.pitch_deg) / prior.inclinometer_sigma_deg, 2);
  if (prior.roll_deg) chi2 += std::pow((pose.roll_deg - *prior.roll_deg) / prior.inclinometer_sigma_deg, 2);
  return chi2;
}

bool WithinPrior(const RegistrationOptions& o, const CameraPose& pose) {
  const SensorPrior& pr = o.prior;
  const double g = pr.gate_sigmas;
  if (pr.compass_deg && std::abs(AngDiffDeg(pose.azimuth_deg, *pr.compass_deg)) > g * pr.compass_sigma_deg)
    return false;
  if (pr.pitch_deg && std::abs(pose.pitch_deg - *pr.pitch_deg) > g * pr.inclinometer_sigma_deg + 1.0) return false;
  if (pr.roll_deg) return std::abs(pose.roll_deg - *pr.roll_deg) <= g * pr.inclinometer_sigma_deg + 1.0;
  return std::abs(pose.roll_deg) <= o.max_abs_roll_deg;
}

struct Candidate {
  Pose4 pose;
  double cost = INFINITY;
  double inliers = 0.0;  // fraction of the columns within tau
};

bool SamePose(const Pose4& a, const Pose4& b, double width) {
  const double hfov = 2.0 * std::atan(0.5 * width / a.f);
  const double tol = std::max(DegToRad(0.5), 0.03 * hfov);
  return std::abs(std::remainder(a.yaw - b.yaw, 2 * kPi)) < tol && std::abs(a.pitch - b.pitch) < tol &&
         std::abs(std::log(a.f / b.f)) < 0.05;
}

// Smallest and largest cosine of the angle between the rays through two
// pixels for focal lengths in [fmin, fmax] (sampled finely on a log grid,
// widened by a margin for what falls between samples).
std::pair<double, double> RayCosineRange(const ImagePoint& p1, const ImagePoint& p2, double cx, double cy, double fmin,
                                         double fmax) {
  const Eigen::Vector2d u1(p1.x - cx, p1.y - cy), u2(p2.x - cx, p2.y - cy);
  double lo = 1.0, hi = -1.0;
  constexpr int kSteps = 48;
  for (int i = 0; i <= kSteps; ++i) {
    const double f = fmin * std::pow(fmax / fmin, static_cast<double>(i) / kSteps), f2 = f * f;
    const double c = (u1.dot(u2) + f2) / std::sqrt((u1.squaredNorm() + f2) * (u2.squaredNorm() + f2));
    lo = std::min(lo, c);
    hi = std::max(hi, c);
  }
  const double margin = 0.02 * (hi - lo) + 1e-9;
  return {lo - margin, hi + margin};
}

// Final robust fit from `start` with covariance, then the statistics and the
// acceptance tests (the ambiguity ratio must already be in `out`).
void FinishRegistration(const Scorer& scorer, std::vector<Column>& all, const Pose4& start, int width, double step,
                        double tau, double px_scale, bool fix_focal, const RegistrationOptions& options,
                        Registration& out) {
  scorer.Reweight(start, all);
  const std::vector<Column> final_cols = Subsample(all, options.refine_columns);
  const double hfov_rad = 2.0 * std::atan(0.5 * width / start.f);
  const double independent = std::min(1.0, RadToDeg(hfov_rad) / step / final_cols.size());
  const Refined fr = RefineLeastSquares(scorer, final_cols, start, tau, 3, true, independent, fix_focal);
  const Pose4 bp = fr.pose;
  const Eigen::Matrix3d m = CamFromEnuRad(bp.yaw, bp.pitch, bp.roll);
  // Near-field columns count by their distance weight: they neither confirm
  // nor refute a pose much.
  scorer.Reweight(bp, all);
  double ss = 0.0, w_in = 0.0, w_all = 0.0;
  for (const Column& c : all) {
    const double r = scorer.Residual(m, bp.f, c);
    const double w = c.fit_weight / c.weight;
    w_all += w;
    if (std::abs(r) < tau) {
      ss += w * r * r;
      w_in += w;
    }
  }
  out.pose = bp.ToPose();
  out.focal_px = bp.f;
  out.hfov_deg = RadToDeg(2.0 * std::atan(0.5 * width / bp.f));
  out.inlier_fraction = w_all > 0 ? w_in / w_all : 0.0;
  out.rms_px = w_in > 0 ? std::sqrt(ss / w_in) : NAN;
  out.azimuth_sigma_deg = RadToDeg(fr.sigma[0]);
  out.pitch_sigma_deg = RadToDeg(fr.sigma[1]);
  out.roll_sigma_deg = RadToDeg(fr.sigma[2]);
  out.focal_sigma_px = fr.sigma[3];
  std::ostringstream why;
  if (out.inlier_fraction < options.min_inlier_fraction)
    why << "only " << std::lround(100 * out.inlier_fraction) << "% of the skyline fits the DEM horizon";
  else if (!(out.rms_px <= options.max_rms_px * px_scale))
    why << "residual " << out.rms_px << " px too large";
  else if (out.ambiguity_ratio < options.min_ambiguity_ratio)
    why << "ambiguous: another pose fits almost as well (cost ratio " << out.ambiguity_ratio << ")";
  out.message = why.str();
  out.registered = out.message.empty();
  if (out.registered) out.message = "registered";
}

}  // namespace

double HorizonDistancePx(const HorizonProfile& horizon, const CameraPose& pose, double focal_px, int width, int height,
                         double x, double y) {
  const HorizonLookup lookup(horizon);
  Column c{x, y, 1.0};
  const Pose4 p = Pose4::From(pose, focal_px);
  Scorer scorer(lookup, width / 2.0, height / 2.0, 1.0);
  std::vector<Column> one{c};
  scorer.Reweight(p, one);
  return scorer.Residual(CamFromEnu(pose), focal_px, one[0]);
}

std::vector<double> ProjectedHorizonRows(const HorizonProfile& horizon, const CameraPose& pose,
                                         const CameraIntrinsics& k) {
  k.Check();
  const Eigen::Matrix3d m = CamFromEnu(pose);
  std::vector<double> rows(k.width, NAN);
  for (int c = 0; c < k.width; ++c) {
    const double x = c + 0.5;
    auto above = [&](double y) {
      const AzEl ae = AzElFromEnu(UnprojectToEnu(m, k, {x, y}));
      return ae.elevation_deg - horizon.ElevationAtDeg(ae.azimuth_deg);
    };
    double lo = -2.0 * k.height, hi = 3.0 * k.height;  // sky at lo, terrain at hi
    if (!(above(lo) > 0 && above(hi) < 0)) continue;
    while (hi - lo > 1e-6) {
      const double mid = 0.5 * (lo + hi);
      (above(mid) > 0 ? lo : hi) = mid;
    }
    rows[c] = 0.5 * (lo + hi);
  }
  return rows;
}

Registration Register(const Skyline& skyline, const HorizonProfile& horizon, const RegistrationOptions& options) {
  options.Check();
  if (skyline.width < 1 || static_cast<int>(skyline.y.size()) != skyline.width)
    throw InvalidArgument("Register: skyline has no columns or y.size() != width");
  if (horizon.size() < 8) throw InvalidArgument("Register: horizon profile has fewer than 8 bins");
  const int width = skyline.width, height = skyline.height;
  const double cx = width / 2.0, cy = height / 2.0;
  const double px_scale = ToleranceScale(width);
  const double tau = options.inlier_px * px_scale;
  Registration out;

  std::vector<Column> all = VisibleColumns(skyline);
  const double visible = static_cast<double>(all.size()) / width;
  if (visible < options.min_visible_fraction) {
    out.message = "too little skyline visible";
    return out;
  }

  // Extrema: image (up positive, pixels) and DEM horizon (degrees).
  // Extrema of the skyline after a running median over a few columns: a spike
  // one or two columns wide (a pole, a misread pixel run) is not a peak.
  const int half = std::max(2, static_cast<int>(std::lround(4 * px_scale)));
  std::vector<double> up(width, NAN), window;
  for (int i = 0; i < width; ++i) {
    if (!std::isfinite(skyline.y[i])) continue;
    window.clear();
    for (int j = std::max(0, i - half); j <= std::min(width - 1, i + half); ++j)
      if (std::isfinite(skyline.y[j])) window.push_back(skyline.y[j]);
    std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
    up[i] = -window[window.size() / 2];
  }
  ExtremaOptions eo;
  eo.min_prominence = options.min_image_prominence_px * px_scale;
  eo.max_count = options.image_extrema;
  std::vector<Extremum> img = FindExtrema(up, false, eo);
  // Keep the most prominent overall.
  std::sort(img.begin(), img.end(), [](const Extremum& a, const Extremum& b) { return a.prominence > b.prominence; });
  if (static_cast<int>(img.size()) > options.image_extrema) img.resize(options.image_extrema);
  std::sort(img.begin(), img.end(), [](const Extremum& a, const Extremum& b) { return a.position < b.position; });
  ExtremaOptions ho;
  ho.min_prominence = options.min_horizon_prominence_deg;
  ho.max_count = options.horizon_extrema;
  const std::vector<Extremum> dem = FindExtrema(horizon.elevation_deg, true, ho);
  out.image_extrema = static_cast<int>(img.size());
  out.horizon_extrema = static_cast<int>(dem.size());
  if (img.size() < 2 || dem.size() < 2) {
    out.message = "too few peaks and dips to form hypotheses";
    return out;
  }

  const HorizonLookup lookup(horizon);
  const Scorer scorer(lookup, cx, cy, tau);
  const std::vector<Column> coarse = Subsample(all, options.coarse_columns);
  const double fmin = 0.5 * width / std::tan(DegToRad(options.max_hfov_deg) / 2.0);
  const double fmax = 0.5 * width / std::tan(DegToRad(options.min_hfov_deg) / 2.0);
  const double step = horizon.azimuth_step_deg;
  auto dem_point = [&](const Extremum& e) { return HorizonPoint{e.position * step, e.value}; };
  std::vector<Eigen::Vector3d> dem_dirs;
  for (const Extremum& e : dem) {
    const double az = DegToRad(e.position * step), el = DegToRad(e.value);
    dem_dirs.emplace_back(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
  }
  auto DirectionOf = [&](const Extremum& e) -> const Eigen::Vector3d& { return dem_dirs[&e - dem.data()]; };

  // Hypotheses: every pair of image extrema far enough apart against every
  // pair of DEM extrema of the same kinds whose angular separation a camera
  // in the opening-angle range could show. The image pairs are shared out
  // among the threads; each keeps its best candidates (pruned against its own
  // 64th best, which only drops hypotheses that cannot be among the best 64).
  struct ImagePair {
    size_t a, b;
  };
  std::vector<ImagePair> pairs;
  const double min_sep = width / 20.0;
  for (size_t a = 0; a < img.size(); ++a)
    for (size_t b = a + 1; b < img.size(); ++b)
      if (img[b].position - img[a].position >= min_sep) pairs.push_back({a, b});
  struct Scored {
    std::vector<Candidate> candidates;
    int hypotheses = 0;
  };
  std::vector<Scored> parts(options.num_threads);
  ParallelFor(pairs.size(), options.num_threads, [&](size_t k, int t) {
    Scored& result = parts[t];
    std::vector<Candidate>& scored = result.candidates;
    const Extremum &ia = img[pairs[k].a], &ib = img[pairs[k].b];
    const ImagePoint p1{ia.position + 0.5, -ia.value}, p2{ib.position + 0.5, -ib.value};
    // The cosines of the angle between the two pixel rays over the focal
    // range: a DEM pair whose angle falls outside cannot be this pair.
    const std::pair<double, double> cos_range = RayCosineRange(p1, p2, cx, cy, fmin, fmax);
    for (const Extremum& da : dem) {
      if (da.is_max != ia.is_max) continue;
      for (const Extremum& db : dem) {
        if (db.is_max != ib.is_max || &da == &db) continue;
        const double sep = WrapAzimuthDeg((db.position - da.position) * step);
        if (sep <= 0.0 || sep > options.max_hfov_deg) continue;
        const double cos_dem = DirectionOf(da).dot(DirectionOf(db));
        if (cos_dem < cos_range.first || cos_dem > cos_range.second) continue;
        for (const PoseHypothesis& hyp : TwoPointPoses(p1, p2, dem_point(da), dem_point(db), cx, cy, fmin, fmax)) {
          const PoseHypothesis* h = &hyp;
          // An image extremum cannot be more prominent than its DEM match
          // (it is seen through a window of the horizon).
          const double to_deg = RadToDeg(1.0 / h->focal_px);
          if (da.prominence < 0.5 * ia.prominence * to_deg - 0.05 ||
              db.prominence < 0.5 * ib.prominence * to_deg - 0.05)
            continue;
          if (!WithinPrior(options, h->pose)) continue;
          ++result.hypotheses;
          const Pose4 pose = Pose4::From(h->pose, h->focal_px);
          const double bound = scored.size() >= 64 ? scored[63].cost : INFINITY;
          const double cost = scorer.Cost(pose, coarse, bound);
          if (!std::isfinite(cost)) continue;
          scored.push_back({pose, cost});
          if (scored.size() >= 256) {  // keep the best 64
            std::partial_sort(scored.begin(), scored.begin() + 64, scored.end(),
                              [](const Candidate& x, const Candidate& y) { return x.cost < y.cost; });
            scored.resize(64);
          }
        }
      }
    }
  });
  std::vector<Candidate> scored;
  for (const Scored& part : parts) {
    out.hypotheses += part.hypotheses;
    scored.insert(scored.end(), part.candidates.begin(), part.candidates.end());
  }
  std::sort(scored.begin(), scored.end(), [](const Candidate& x, const Candidate& y) { return x.cost < y.cost; });
  if (scored.empty()) {
    out.message = "no hypothesis within the opening-angle range and priors";
    return out;
  }

  // Refine the best distinct hypotheses.
  std::vector<Candidate> distinct;
  for (const Candidate& c : scored) {
    if (static_cast<int>(distinct.size()) >= options.candidates) break;
    if (std::none_of(distinct.begin(), distinct.end(),
                     [&](const Candidate& d) { return SamePose(d.pose, c.pose, width); }))
      distinct.push_back(c);
  }
  // Stage 1: the paper's linear corrections (eq. 11-14) on a few columns.
  std::vector<Column> quick = Subsample(all, options.quick_columns);
  std::vector<PaperCorrection> corrections(distinct.size(), PaperCorrection{});
  ParallelFor(distinct.size(), options.num_threads, [&](size_t i, int) {
    Candidate& c = distinct[i];
    const PaperCorrection pc = CorrectLinear(scorer, quick, c.pose, width, tau, horizon);
    const double corrected = scorer.Cost(pc.pose, quick);
    c.cost = scorer.Cost(c.pose, quick);
    if (corrected < c.cost) c = {pc.pose, corrected};
    corrections[i] = pc;
  });
  std::vector<size_t> by_cost(distinct.size());
  std::iota(by_cost.begin(), by_cost.end(), 0);
  std::sort(by_cost.begin(), by_cost.end(), [&](size_t x, size_t y) { return distinct[x].cost < distinct[y].cost; });
  // Stage 2: robust least squares for the best few, ranked on all columns.
  const size_t n_refine = std::min(by_cost.size(), static_cast<size_t>(options.refined_candidates));
  std::vector<std::optional<Candidate>> slots(n_refine);
  ParallelFor(n_refine, options.num_threads, [&](size_t k, int) {
    const Candidate& c = distinct[by_cost[k]];
    std::vector<Column> cols = quick;  // weighted for this candidate's pose
    scorer.Reweight(c.pose, cols);
    const Refined r = RefineLeastSquares(scorer, cols, c.pose, tau, 2, false, 1.0);
    Candidate rc{r.pose, 0.0};
    const CameraPose cp = rc.pose.ToPose();
    if (!WithinPrior(options, cp)) return;
    const double hfov = RadToDeg(2.0 * std::atan(0.5 * width / rc.pose.f));
    if (hfov < options.min_hfov_deg * 0.95 || hfov > options.max_hfov_deg * 1.05) return;
    rc.cost = scorer.Cost(rc.pose, all) + 0.02 * PriorPenalty(options.prior, cp) * scorer.tau2() / 9.0;
    rc.inliers = scorer.InlierFraction(rc.pose, all);
    slots[k] = rc;
  });
  std::vector<Candidate> refined;
  std::vector<PaperCorrection> refined_corrections;
  for (size_t k = 0; k < n_refine; ++k)
    if (slots[k]) {
      refined.push_back(*slots[k]);
      refined_corrections.push_back(corrections[by_cost[k]]);
    }
  corrections = std::move(refined_corrections);
  if (refined.empty()) {
    out.message = "no refined hypothesis within the opening-angle range and priors";
    return out;
  }
  std::vector<size_t> order(refined.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return refined[x].cost < refined[y].cost; });
  const Candidate& best = refined[order[0]];
  double second = INFINITY;
  for (size_t i = 1; i < order.size(); ++i)
    if (!SamePose(refined[order[i]].pose, best.pose, width)) {
      second = refined[order[i]].cost;
      out.second_inlier_fraction = refined[order[i]].inliers;
      break;
    }

  out.ambiguity_ratio = second / std::max(best.cost, 1e-9 * scorer.tau2());
  out.ex_px = corrections[order[0]].ex_px;
  out.ey_px = corrections[order[0]].ey_px;
  FinishRegistration(scorer, all, best.pose, width, step, tau, px_scale, false, options, out);
  return out;
}

Registration RefinePose(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start, double focal_px,
                        bool fix_focal, const RegistrationOptions& options) {
  options.Check();
  if (skyline.width < 1 || static_cast<int>(skyline.y.size()) != skyline.width)
    throw InvalidArgument("RefinePose: skyline has no columns or y.size() != width");
  if (horizon.size() < 8) throw InvalidArgument("RefinePose: horizon profile has fewer than 8 bins");
  if (!(focal_px > 0.0)) throw InvalidArgument("RefinePose: focal_px must be > 0");
  const int width = skyline.width;
  const double px_scale = ToleranceScale(width);
  const double tau = options.inlier_px * px_scale;
  Registration out;
  std::vector<Column> all = VisibleColumns(skyline);
  if (static_cast<double>(all.size()) / width < options.min_visible_fraction || all.size() < 8) {
    out.message = "too little skyline visible";
    return out;
  }
  const HorizonLookup lookup(horizon);
  const Scorer scorer(lookup, width / 2.0, skyline.height / 2.0, tau);
  out.ambiguity_ratio = INFINITY;  // not searched: the start pose is given
  FinishRegistration(scorer, all, Pose4::From(start, focal_px), width, horizon.azimuth_step_deg, tau, px_scale,
                     fix_focal, options, out);
  return out;
}

}  // namespace horizonreg
