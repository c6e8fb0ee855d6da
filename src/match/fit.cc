// SPDX-License-Identifier: MIT
#include "match/fit.h"

#include <ceres/ceres.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <ceres/manifold.h>

#include <algorithm>
#include <cmath>

#include "util/fast_math.h"

namespace horizonreg::match_detail {

namespace {
constexpr double kMinSharpness = 0.25, kMaxSharpness = 4.0;  // DemErrorModel::typical_slope's range
}  // namespace

HorizonLookup::HorizonLookup(const HorizonProfile& p, const DemErrorModel& model)
    : profile_(&p),
      n_(p.size()),
      step_rad_(DegToRad(p.azimuth_step_deg)),
      el_(static_cast<size_t>(n_) + 1),
      distance_m_(n_),
      flattening_rad_(n_),
      position_rad_(n_),
      spacing_m_(n_) {
  const double floor_rad = DegToRad(model.flattening_floor_deg);
  const double position_m = std::hypot(model.position_sigma_m, model.height_sigma_m);
  std::vector<double> flat(n_), pos(n_), spacing(n_);
  for (int i = 0; i < n_; ++i) {
    el_[i] = DegToRad(p.elevation_deg[i]);
    const double d = std::isfinite(p.distance_m[i]) ? std::max(p.distance_m[i], 1.0) : 1e9;
    spacing[i] = i < static_cast<int>(p.post_spacing_m.size()) ? p.post_spacing_m[i] : NAN;
    const double slope = i < static_cast<int>(p.relief_slope.size()) && std::isfinite(p.relief_slope[i])
                             ? p.relief_slope[i]
                             : model.typical_slope;
    const double sharpness = std::clamp(slope / model.typical_slope, kMinSharpness, kMaxSharpness);
    const double cut_m = std::isfinite(spacing[i]) ? model.flattening_spacings * spacing[i] * sharpness : 0.0;
    flat[i] = std::hypot(cut_m / d, floor_rad);
    pos[i] = position_m / d;
  }
  el_[n_] = el_[0];
  for (int i = 0; i < n_; ++i) {
    const int j = (i + 1) % n_;
    const double di = std::isfinite(p.distance_m[i]) ? p.distance_m[i] : 1e9;
    const double dj = std::isfinite(p.distance_m[j]) ? p.distance_m[j] : 1e9;
    distance_m_[i] = std::min(di, dj);
    flattening_rad_[i] = std::max(flat[i], flat[j]);
    position_rad_[i] = std::max(pos[i], pos[j]);
    spacing_m_[i] = std::isfinite(spacing[i]) && std::isfinite(spacing[j]) ? std::max(spacing[i], spacing[j])
                                                                            : (std::isfinite(spacing[i]) ? spacing[i] : spacing[j]);
  }
}

double ColumnLoss::LogNorm() const {
  constexpr double kSqrtHalfPi = 1.2533141373155003;
  if (!std::isfinite(kappa)) return std::log(2.0 * kSqrtHalfPi * s);
  const double z = kappa / s;
  return std::log(kSqrtHalfPi * s * (1.0 + std::erf(z / std::sqrt(2.0))) + s * s / kappa * std::exp(-0.5 * z * z));
}

double ColumnLoss::ExpectedChi2() const {
  if (!std::isfinite(kappa)) return 1.0;
  const double z = kappa / s;
  const double excess_mass = s * s / kappa * std::exp(-0.5 * z * z) / std::exp(LogNorm());
  return (1.0 - excess_mass) + excess_mass * (2.0 + z * z);
}

Scorer::Scorer(const HorizonLookup& horizon, const DemErrorModel& model, double sigma_px, double image_height_px,
               double outlier_share)
    : horizon_(horizon),
      model_(model),
      sigma_px_(sigma_px),
      log_outlier_density_(std::log(outlier_share) - std::log(std::max(1.0, image_height_px))),
      log_inlier_prior_(std::log(1.0 - outlier_share)) {}

double Scorer::Residual(const Eigen::Matrix3d& m, const Pose4& p, const Column& c) const {
  return ColumnResidual<double>(m, p.f, p.k1, c, horizon_);
}

double Scorer::Sum(const Pose4& p, const std::vector<Column>& cols, double bound, bool width) const {
  const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
  const double limit = bound * cols.size();
  double sum = 0.0;
  for (const Column& c : cols) {
    double xn, yn;
    Undistorted(c, p.f, p.k1, xn, yn);
    const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
    const double h = std::sqrt(d.x() * d.x() + d.y() * d.y());
    const double az = FastAtan2(d.x(), d.y()), el = FastAtan2(d.z(), h);
    const double r = (horizon_(az) - el) * p.f * (1.0 + yn * yn) * std::sqrt(1.0 + xn * xn);
    const double noise = std::hypot(sigma_px_, p.f * horizon_.PositionSigmaRad(az));
    const ColumnLoss loss(noise, p.f * horizon_.FlatteningRad(az));
    sum += std::min(loss.Chi2(r) + (width ? loss.WidthCost(sigma_px_) : 0.0), kGateChi2);
    if (sum > limit) return INFINITY;
  }
  return sum / cols.size();
}

double Scorer::Misfit(const Pose4& p, const std::vector<Column>& cols) const { return Sum(p, cols, INFINITY, false); }

double Scorer::Agreement(const Pose4& a, const Pose4& b, const std::vector<Column>& cols, double tol_px) const {
  const Eigen::Matrix3d ma = CamFromEnuRad(a.yaw, a.pitch, a.roll), mb = CamFromEnuRad(b.yaw, b.pitch, b.roll);
  int n = 0;
  for (const Column& c : cols) n += std::abs(Residual(ma, a, c) - Residual(mb, b, c)) < tol_px;
  return cols.empty() ? 0.0 : static_cast<double>(n) / cols.size();
}

double Scorer::InlierShare(const Pose4& p, const std::vector<Column>& cols) const {
  std::vector<Column> c = cols;
  Reweight(p, c);
  const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
  int n = 0;
  for (const Column& col : c) n += ColumnLoss(col).Chi2(Residual(m, p, col)) <= kGateChi2;
  return c.empty() ? 0.0 : static_cast<double>(n) / c.size();
}

void Scorer::Reweight(const Pose4& p, std::vector<Column>& cols) const {
  const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
  for (Column& c : cols) {
    double xn, yn;
    Undistorted(c, p.f, p.k1, xn, yn);
    const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
    const double az = std::atan2(d.x(), d.y());
    const double s = horizon_.Slope(az) / std::max(0.05, std::hypot(d.x(), d.y()) / d.norm());
    c.slope_weight = 1.0 / std::sqrt(1.0 + s * s);
    c.noise_px = std::hypot(sigma_px_, p.f * horizon_.PositionSigmaRad(az) * c.slope_weight);
    c.flattening_px = p.f * horizon_.FlatteningRad(az) * c.slope_weight;
  }
}

double Scorer::InlierProbability(const Column& c, double r, double noise_scale) const {
  const ColumnLoss loss(c.noise_px * noise_scale, c.flattening_px);
  const double log_in = log_inlier_prior_ - 0.5 * loss.Chi2(r) - loss.LogNorm();
  return 1.0 / (1.0 + std::exp(std::clamp(log_outlier_density_ - log_in, -50.0, 50.0)));
}

namespace {

// All columns in one residual block (the rotation is built once per
// evaluation): column i's residual times sqrt(w_i), its IRLS weight.
struct AllColumnsCost {
  const std::vector<Column>* cols;
  const std::vector<double>* sqrt_w;
  const HorizonLookup* horizon;
  bool fit_k1;  // false: k1 is held (the undistortion is skipped when it is 0)
  template <typename T>
  bool operator()(T const* const* params, T* residuals) const {
    const T* p = params[0];
    const Eigen::Matrix<T, 3, 3> m = CamFromEnuRad(p[0], p[1], p[2]);
    const bool undistort = fit_k1 || ScalarOf(p[4]) != 0.0;
    for (size_t i = 0; i < cols->size(); ++i)
      residuals[i] = (undistort ? ColumnResidual<T>(m, p[3], p[4], (*cols)[i], *horizon)
                                : ColumnResidual<T>(m, p[3], T(0.0), (*cols)[i], *horizon, false)) *
                     (*sqrt_w)[i];
    return true;
  }
};

// k1's prior: 0 with sigma s.
struct K1Prior {
  double inv_sigma;
  template <typename T>
  bool operator()(const T* p, T* r) const {
    r[0] = p[4] * inv_sigma;
    return true;
  }
};

}  // namespace

Refined RefineLeastSquares(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start,
                           const LeastSquaresOptions& options) {
  double p[5] = {start.yaw, start.pitch, start.roll, start.f, options.fit_k1 ? start.k1 : start.k1};
  std::vector<double> sqrt_w(cols.size(), 1.0);
  auto reweight = [&](double scale) {
    const Eigen::Matrix3d m = CamFromEnuRad(p[0], p[1], p[2]);
    const Pose4 now{p[0], p[1], p[2], p[3], p[4]};
    for (size_t i = 0; i < cols.size(); ++i) {
      const double r = scorer.Residual(m, now, cols[i]);
      const ColumnLoss loss(cols[i].noise_px * scale, cols[i].flattening_px);
      sqrt_w[i] = std::sqrt(loss.Weight(r) * scorer.InlierProbability(cols[i], r, scale));
    }
  };
  // Stride 5: the derivatives of all five parameters in one pass.
  auto* cost = new ceres::DynamicAutoDiffCostFunction<AllColumnsCost, 5>(
      new AllColumnsCost{&cols, &sqrt_w, &scorer.horizon(), options.fit_k1});
  cost->AddParameterBlock(5);
  cost->SetNumResiduals(static_cast<int>(cols.size()));
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, p);
  std::vector<int> fixed;
  if (options.fix_focal) fixed.push_back(3);
  if (!options.fit_k1) fixed.push_back(4);
  if (options.fit_k1)
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<K1Prior, 1, 5>(new K1Prior{1.0 / options.k1_prior_sigma}), nullptr, p);
  if (!fixed.empty()) problem.SetManifold(p, new ceres::SubsetManifold(5, fixed));
  if (!options.fix_focal && options.bound_focal) {
    problem.SetParameterLowerBound(p, 3, 0.2 * start.f);
    problem.SetParameterUpperBound(p, 3, 5.0 * start.f);
  }
  if (options.fit_k1) {
    problem.SetParameterLowerBound(p, 4, -kK1Bound);
    problem.SetParameterUpperBound(p, 4, kK1Bound);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 10;
  so.function_tolerance = 1e-8;
  so.logging_type = ceres::SILENT;
  so.num_threads = 1;
  std::vector<double> scales = options.anneal;
  for (int round = 0; round < options.rounds; ++round) scales.push_back(1.0);
  for (double scale : scales) {
    reweight(scale);
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
  }
  Refined r;
  r.pose = {p[0], p[1], p[2], p[3], p[4]};
  if (!options.want_covariance) return r;
  // The weighted residuals have unit variance if the noise model is right;
  // scale by what they show (the inliers': chi^2 per degree of freedom).
  const Eigen::Matrix3d m = CamFromEnuRad(p[0], p[1], p[2]);
  double chi2 = 0.0, n = 0.0;
  for (size_t i = 0; i < cols.size(); ++i) {
    const double res = scorer.Residual(m, r.pose, cols[i]);
    const double g = scorer.InlierProbability(cols[i], res);
    if (g < 0.5) continue;
    chi2 += ColumnLoss(cols[i]).Chi2(res);
    n += 1.0;
  }
  const int free_params = 5 - static_cast<int>(fixed.size());
  if (n <= free_params + 2) return r;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{p, p}};
  if (!covariance.Compute(blocks, &problem)) return r;
  double cov[25];
  covariance.GetCovarianceBlock(p, p, cov);
  // Neighbouring columns share DEM bins and skyline pixels: count only the
  // independent ones (effective_fraction of the columns).
  const double variance = std::max(chi2 / (n - free_params), 1e-3) / std::clamp(options.effective_fraction, 1e-3, 1.0);
  for (int i = 0; i < 5; ++i) r.sigma[i] = std::sqrt(std::max(0.0, cov[i * 6] * variance));
  if (options.fix_focal) r.sigma[3] = 0.0;
  if (!options.fit_k1) r.sigma[4] = NAN;
  return r;
}

PaperCorrection CorrectLinear(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start, int width,
                              double tau) {
  PaperCorrection out{start};
  const HorizonProfile& profile = scorer.horizon().profile();
  for (int iter = 0; iter < 2; ++iter) {
    const Pose4& p = out.pose;
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    // A pinhole with its principal point at the origin of (u, v).
    CameraIntrinsics k;
    k.width = width;
    k.height = width;
    k.focal_px = p.f;
    // DEM silhouette polyline in the image, bins within the field of view.
    const double half = std::atan(0.6 * width / p.f) + 0.02;
    std::vector<Eigen::Vector2d> poly;
    const int n = profile.size();
    const int span = static_cast<int>(std::ceil(RadToDeg(half) / profile.azimuth_step_deg)) + 1;
    const int centre = static_cast<int>(std::lround(WrapAzimuthDeg(RadToDeg(p.yaw)) / profile.azimuth_step_deg));
    for (int j = centre - span; j <= centre + span; ++j) {
      const int b = ((j % n) + n) % n;
      if (auto px = ProjectAzEl(m, k, j * profile.azimuth_step_deg, profile.elevation_deg[b])) poly.push_back(*px);
    }
    if (poly.size() < 2) return out;
    // Closest points. Segment i reaches the column's window [u - 3 tau,
    // u + 3 tau] only if the running maximum of the segments' right ends
    // has reached the window's left edge by i and the running minimum of
    // their left ends from i on is within its right edge: both monotone, so
    // two binary searches bound the segments looked at (the polyline runs
    // left to right but for roll and steep slopes). The same segments in
    // the same order as a scan of all of them: the same result, without
    // the scan (8% of a registration's time with the position check's wide
    // look, 1% now).
    const size_t segments = poly.size() - 1;
    std::vector<double> reach_right(segments), reach_left(segments);
    for (size_t i = 0; i < segments; ++i)
      reach_right[i] = std::max(i ? reach_right[i - 1] : -INFINITY, std::max(poly[i].x(), poly[i + 1].x()));
    for (size_t i = segments; i-- > 0;)
      reach_left[i] = std::min(i + 1 < segments ? reach_left[i + 1] : INFINITY, std::min(poly[i].x(), poly[i + 1].x()));
    std::vector<double> xs, dxs, ys, dys;
    for (const Column& c : cols) {
      double best = INFINITY;
      Eigen::Vector2d q;
      const Eigen::Vector2d s(c.u, c.v);
      const size_t from =
          std::lower_bound(reach_right.begin(), reach_right.end(), c.u - 3 * tau) - reach_right.begin();
      const size_t to = std::upper_bound(reach_left.begin(), reach_left.end(), c.u + 3 * tau) - reach_left.begin();
      for (size_t i = from; i < to; ++i) {
        const Eigen::Vector2d a = poly[i], e = poly[i + 1];
        if (std::max(a.x(), e.x()) < c.u - 3 * tau || std::min(a.x(), e.x()) > c.u + 3 * tau) continue;
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
      xs.push_back(c.u);
      ys.push_back(-c.v);
      dxs.push_back(q.x() - c.u);
      dys.push_back(c.v - q.y());  // up positive
    }
    const int count = static_cast<int>(xs.size());
    out.matched = count;
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

namespace {
double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Misses above the DEM horizon in runs that rise out of the fitted skyline:
// something nearer than the DEM shows (a tree, a roof, a cap cloud) can
// only hide the horizon behind it, so that the sky's edge runs above it.
// A run counts when it spans at least kMinOccluderShare of the width, holds
// no miss below, and meets columns inside the gate (or the frame's edge) at
// both ends. Runs hiding more than kMaxOccludedShare of the columns in all
// count for nothing: what is seen is then mostly not the horizon.
constexpr double kMinOccluderShare = 0.015, kMaxOccludedShare = 0.4, kMaxUnreadShare = 0.1;
int OccludedRuns(const std::vector<Column>& cols, const std::vector<signed char>& side, int width) {
  if (width <= 0 || cols.empty()) return 0;
  const double gap = std::max(2.0, 4.0 * width / 1024.0);  // from the frame's edge
  // Columns not read inside or beside a run (a chimney, a pole's top) do not end it.
  const auto joined = [&](size_t a, size_t b) { return cols[b].x_px - cols[a].x_px <= kMaxUnreadShare * width; };
  int hidden = 0;
  for (size_t i = 0; i < cols.size();) {
    if (side[i] != -1) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j + 1 < cols.size() && side[j + 1] == -1 && joined(j, j + 1)) ++j;
    const bool left = i == 0 ? cols[i].x_px <= gap : (side[i - 1] == 0 && joined(i - 1, i)) || cols[i].x_px <= gap;
    const bool right = j + 1 == cols.size() ? cols[j].x_px >= width - 1 - gap
                                            : (side[j + 1] == 0 && joined(j, j + 1)) || cols[j].x_px >= width - 1 - gap;
    const int n = static_cast<int>(j - i + 1);
    if (left && right && n >= kMinOccluderShare * width) hidden += n;
    i = j + 1;
  }
  return hidden <= kMaxOccludedShare * cols.size() ? hidden : 0;
}
}  // namespace

FitStats ComputeFitStats(const Scorer& scorer, const Pose4& p, const std::vector<Column>& cols, int width) {
  FitStats s;
  std::vector<signed char> side(cols.size(), 0);  // 0 inside the gate, +1 a miss below, -1 above
  const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
  const double sigma = scorer.sigma_px();
  double w_all = 0, w_in = 0, ss_raw = 0, ss_chi = 0, ss_expected = 0;
  int explained = 0, inliers = 0, outliers = 0;
  std::vector<double> spacing, distance, flattening, above;
  for (const Column& c : cols) {
    const double r = scorer.Residual(m, p, c);
    const ColumnLoss loss(c);
    const double chi2 = loss.Chi2(r);
    // A column informs as much as its tolerance allows, up to one column:
    // those whose noise and DEM flattening stay within 3 sigma count fully,
    // near terrain (the position's noise and the DEM's error are many
    // sigmas there) counts little.
    const double info = std::min(
        1.0, 9.0 * (sigma * sigma) / (c.noise_px * c.noise_px + c.flattening_px * c.flattening_px));
    w_all += info;
    if (!(chi2 <= kGateChi2)) {
      ++outliers;  // a miss beyond even a wide tolerance refutes the pose, however little the column informs
      ++(r > 0.0 ? s.outliers_below : s.outliers_above);
      side[&c - cols.data()] = r > 0.0 ? 1 : -1;
      continue;
    }
    w_in += info;
    ss_raw += info * r * r;
    ss_chi += info * chi2;
    ss_expected += info * loss.ExpectedChi2();
    ++inliers;
    explained += -r > 3.0 * c.noise_px;
    double xn, yn;
    Undistorted(c, p.f, p.k1, xn, yn);
    const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
    const double az = std::atan2(d.x(), d.y());
    spacing.push_back(scorer.horizon().PostSpacingM(az));
    {
      const double sp = scorer.horizon().PostSpacingM(az);
      const double cell = std::max(scorer.horizon().step_rad(),
                                   std::isfinite(sp) ? sp / std::max(1.0, scorer.horizon().DistanceM(az)) : 0.0);
      // Neighbouring columns share the DEM's error over a cell: as far as
      // that error dominates the column's variance, the cell's columns count
      // as one; as far as the pixel noise does, each counts.
      const double per_cell = std::max(1.0, cell * p.f);
      const double dem_share =
          c.flattening_px * c.flattening_px / (c.flattening_px * c.flattening_px + c.noise_px * c.noise_px);
      s.independent_inliers += info / (1.0 + (per_cell - 1.0) * dem_share);
    }
    distance.push_back(scorer.horizon().DistanceM(az));
    flattening.push_back(c.flattening_px);
    above.push_back(-r);
  }
  // Inliers count by their information, outliers fully (in the second share
  // not those hidden by something in front).
  s.inlier_fraction = w_in + outliers > 0 ? w_in / (w_in + outliers) : 0.0;
  s.hidden_columns = OccludedRuns(cols, side, width);
  const int refuting = outliers - s.hidden_columns;
  s.unhidden_inlier_fraction = w_in + refuting > 0 ? w_in / (w_in + refuting) : 0.0;
  s.informative_columns = w_all;
  if (w_in > 0) {
    s.rms_px = std::sqrt(ss_raw / w_in);
    s.model_rms_px = std::sqrt(ss_chi / ss_expected) * sigma;
  }
  std::erase_if(spacing, [](double v) { return !std::isfinite(v); });
  s.dem.post_spacing_m = Median(spacing);
  s.dem.horizon_distance_m = Median(distance);
  s.dem.expected_flattening_px = Median(flattening);
  s.dem.skyline_above_dem_px = Median(above);
  s.dem.dem_explained_fraction = inliers > 0 ? static_cast<double>(explained) / inliers : NAN;
  return s;
}

std::vector<Column> VisibleColumns(const Skyline& skyline, const ImageFrame& frame) {
  std::vector<Column> all;
  for (int i = 0; i < skyline.width; ++i) {
    const double y = skyline.MatchY(i);
    if (!std::isfinite(y)) continue;
    const auto uv = frame.Offset(i + 0.5, y);
    if (!uv) continue;
    Column c;
    c.u = uv->x();
    c.v = uv->y();
    c.x_px = i + 0.5;
    all.push_back(c);
  }
  return all;
}

std::vector<Column> Subsample(const std::vector<Column>& all, int count) {
  if (static_cast<int>(all.size()) <= count) return all;
  std::vector<Column> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) out.push_back(all[(static_cast<size_t>(i) * all.size() + all.size() / 2) / count]);
  return out;
}

}  // namespace horizonreg::match_detail
