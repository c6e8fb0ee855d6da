// SPDX-License-Identifier: MIT
#include "match/position_fit.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "match/fit.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

using match_detail::Column;
using match_detail::ColumnLoss;
using match_detail::HorizonLookup;
using match_detail::ImageFrame;
using match_detail::kGateChi2;
using match_detail::Pose4;
using match_detail::Scorer;

std::vector<Eigen::Vector3d> HorizonPositionGradient(const HorizonProfile& h) {
  const int n = h.size();
  std::vector<Eigen::Vector3d> g(n, Eigen::Vector3d::Zero());
  if (n < 3) return g;
  const double step = DegToRad(h.azimuth_step_deg);
  // Neighbours count for the slope when at a similar distance (the same ridge).
  auto similar = [&](int i, int j) {
    const double a = h.distance_m[i], b = h.distance_m[j];
    return std::isfinite(h.elevation_deg[j]) && std::isfinite(b) && std::abs(a - b) <= 0.25 * std::min(a, b);
  };
  for (int i = 0; i < n; ++i) {
    const double d = h.distance_m[i];
    if (!std::isfinite(h.elevation_deg[i]) || !(d > 0.0)) continue;
    const int prev = (i + n - 1) % n, next = (i + 1) % n;
    const bool p = similar(i, prev), q = similar(i, next);
    double slope = 0.0;  // d elevation / d azimuth, radians per radian
    if (p && q)
      slope = DegToRad(h.elevation_deg[next] - h.elevation_deg[prev]) / (2.0 * step);
    else if (q)
      slope = DegToRad(h.elevation_deg[next] - h.elevation_deg[i]) / step;
    else if (p)
      slope = DegToRad(h.elevation_deg[i] - h.elevation_deg[prev]) / step;
    const double az = DegToRad(h.AzimuthDeg(i)), el = DegToRad(h.elevation_deg[i]);
    const Eigen::Vector3d along(std::sin(az), std::cos(az), 0.0), across(std::cos(az), -std::sin(az), 0.0);
    g[i] = (along * std::sin(el) * std::cos(el) + across * slope - Eigen::Vector3d::UnitZ() * std::cos(el) * std::cos(el)) / d;
  }
  return g;
}

PoseAndPositionFit FitPoseAndPosition(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start,
                                      double focal_px, double k1, bool free_k1, bool fix_focal,
                                      const Eigen::Vector3d& offset_enu_m, const Eigen::Vector3d& prior_sigma_enu_m,
                                      const RegistrationOptions& options, double flattening_scale, int iterations,
                                      const Eigen::Vector3d& free_axes, double prior_weight) {
  options.Check();
  if (skyline.width < 1 || static_cast<int>(skyline.y.size()) != skyline.width)
    throw InvalidArgument("FitPoseAndPosition: skyline has no columns or y.size() != width");
  if (horizon.size() < 8) throw InvalidArgument("FitPoseAndPosition: horizon profile has fewer than 8 bins");
  if (!(focal_px > 0.0)) throw InvalidArgument("FitPoseAndPosition: focal_px must be > 0");
  if (!(prior_sigma_enu_m.minCoeff() > 0.0)) throw InvalidArgument("FitPoseAndPosition: prior sigmas must be > 0");
  if (iterations < 1) throw InvalidArgument("FitPoseAndPosition: iterations must be >= 1");
  if (!(prior_weight > 0.0 && prior_weight <= 1.0))
    throw InvalidArgument("FitPoseAndPosition: prior_weight must be in (0, 1]");
  const int width = skyline.width;
  const ImageFrame frame(skyline, options.known_intrinsics);
  std::vector<Column> cols = match_detail::Subsample(match_detail::VisibleColumns(skyline, frame), options.refine_columns);
  PoseAndPositionFit out;
  out.columns = static_cast<int>(cols.size());
  out.pose = start;
  out.focal_px = frame.known() ? frame.KnownFocalPx() : focal_px;
  out.k1 = frame.known() ? 0.0 : k1;
  if (cols.size() < 8) return out;
  const bool hold_f = fix_focal || frame.known();
  const bool fit_k1 = free_k1 && !frame.known();
  const double k1_inv_var = 1.0 / (options.distortion_prior_sigma * options.distortion_prior_sigma);
  const DemErrorModel model =
      match_detail::ScaledModel(options.dem_error, std::isfinite(flattening_scale) ? flattening_scale : 1.0);
  const HorizonLookup lookup(horizon, model);
  const Scorer scorer(lookup, model, match_detail::SigmaPx(options, width), skyline.height, options.outlier_share);
  const std::vector<Eigen::Vector3d> grad = HorizonPositionGradient(horizon);
  const double step_rad = DegToRad(horizon.azimuth_step_deg);
  const int n_bins = horizon.size();
  auto gradient_at = [&](double az) {  // linear between bin centres, as HorizonLookup
    const double u = az / step_rad, fl = std::floor(u);
    const int i = static_cast<int>(((static_cast<long long>(fl) % n_bins) + n_bins) % n_bins);
    const double t = u - fl;
    return Eigen::Vector3d(grad[i] * (1.0 - t) + grad[(i + 1) % n_bins] * t);
  };
  const Eigen::Vector3d inv_var = prior_sigma_enu_m.cwiseInverse().cwiseAbs2();
  const Eigen::Vector3d limit = 3.0 * prior_sigma_enu_m;

  Pose4 p = Pose4::From(start, out.focal_px, out.k1);
  Eigen::Vector3d step = Eigen::Vector3d::Zero();
  // Parameters: yaw, pitch, roll (radians), focal length (px), east, north,
  // up (metres), k1 (held at its start unless fit_k1).
  using Mat7 = Eigen::Matrix<double, 7, 7>;
  using Mat8 = Eigen::Matrix<double, 8, 8>;
  using Vec8 = Eigen::Matrix<double, 8, 1>;
  Mat8 a_data = Mat8::Zero();
  double chi2_in = 0.0, expected_in = 0.0, cost = 0.0, inliers = 0.0;
  // One pass: the residuals at (p, step), their Jacobian and IRLS weights.
  auto accumulate = [&]() {
    scorer.Reweight(p, cols);
    a_data.setZero();
    Vec8 b = Vec8::Zero();
    chi2_in = expected_in = cost = inliers = 0.0;
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    const double h_ang = 1e-6, h_f = 1e-5 * p.f, h_k1 = 1e-6;
    Pose4 q[10];
    Eigen::Matrix3d mq[10];
    for (int k = 0; k < 5; ++k)
      for (int s = 0; s < 2; ++s) {
        Pose4 v = p;
        const double sign = s == 0 ? 1.0 : -1.0;
        if (k == 0) v.yaw += sign * h_ang;
        if (k == 1) v.pitch += sign * h_ang;
        if (k == 2) v.roll += sign * h_ang;
        if (k == 3) v.f += sign * h_f;
        if (k == 4) v.k1 += sign * h_k1;
        q[2 * k + s] = v;
        mq[2 * k + s] = CamFromEnuRad(v.yaw, v.pitch, v.roll);
      }
    for (const Column& c : cols) {
      double xn, yn;
      match_detail::Undistorted(c, p.f, p.k1, xn, yn);
      const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
      const double az = std::atan2(d.x(), d.y());
      const double factor = p.f * (1.0 + yn * yn) * std::sqrt(1.0 + xn * xn) * c.slope_weight;
      const Eigen::Vector3d g = gradient_at(az) * factor;
      const double r = scorer.Residual(m, p, c) + g.dot(step);
      Vec8 j;
      for (int k = 0; k < 4; ++k) {
        const double hk = k == 3 ? h_f : h_ang;
        j(k) = (scorer.Residual(mq[2 * k], q[2 * k], c) - scorer.Residual(mq[2 * k + 1], q[2 * k + 1], c)) / (2 * hk);
      }
      if (hold_f) j(3) = 0.0;
      j.segment<3>(4) = g.cwiseProduct(free_axes);
      j(7) = fit_k1 ? (scorer.Residual(mq[8], q[8], c) - scorer.Residual(mq[9], q[9], c)) / (2 * h_k1) : 0.0;
      const ColumnLoss loss(c);
      const double prob = scorer.InlierProbability(c, r);
      const double w = loss.Weight(r) * prob;
      a_data += w * j * j.transpose();
      b += w * r * j;
      const double chi2 = loss.Chi2(r);
      cost += std::min(chi2, kGateChi2);
      if (chi2 <= kGateChi2) inliers += 1.0;
      if (prob >= 0.5) chi2_in += chi2, expected_in += loss.ExpectedChi2();
    }
    cost /= cols.size();
    inliers /= cols.size();
    return b;
  };
  // The robust objective at (q, at_step): truncated chi^2 over the columns
  // (reweighted for q) plus the prior's, for the Levenberg-Marquardt test.
  std::vector<Column> trial_cols = cols;
  auto objective = [&](const Pose4& q, const Eigen::Vector3d& at_step) {
    scorer.Reweight(q, trial_cols);
    const Eigen::Matrix3d m = CamFromEnuRad(q.yaw, q.pitch, q.roll);
    double sum = 0.0;
    for (const Column& c : trial_cols) {
      double xn, yn;
      match_detail::Undistorted(c, q.f, q.k1, xn, yn);
      const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
      const double factor = q.f * (1.0 + yn * yn) * std::sqrt(1.0 + xn * xn) * c.slope_weight;
      const double r = scorer.Residual(m, q, c) + factor * gradient_at(std::atan2(d.x(), d.y())).dot(at_step);
      sum += std::min(ColumnLoss(c).Chi2(r), kGateChi2);
    }
    return sum + prior_weight * (offset_enu_m + at_step).cwiseProduct(inv_var.cwiseSqrt()).squaredNorm() +
           (fit_k1 ? q.k1 * q.k1 * k1_inv_var : 0.0);
  };
  double lambda = 1e-3;
  for (int it = 0; it < iterations; ++it) {
    const Vec8 b0 = accumulate();
    const double before = objective(p, step);
    Mat8 a = a_data;
    Vec8 b = b0;
    const Eigen::Vector3d at = offset_enu_m + step;
    for (int k = 0; k < 3; ++k) {
      a(4 + k, 4 + k) += prior_weight * inv_var(k);
      b(4 + k) += prior_weight * inv_var(k) * at(k);
    }
    if (hold_f) a(3, 3) += 1.0;
    for (int k = 4; k < 7; ++k)
      if (free_axes(k - 4) == 0.0) a.row(k).setZero(), a.col(k).setZero(), a(k, k) = 1.0, b(k) = 0.0;
    if (fit_k1)
      a(7, 7) += k1_inv_var, b(7) += k1_inv_var * p.k1;
    else
      a.row(7).setZero(), a.col(7).setZero(), a(7, 7) = 1.0, b(7) = 0.0;
    bool improved = false;
    for (int tries = 0; tries < 6 && !improved; ++tries, lambda *= 10.0) {
      Mat8 damped = a;
      for (int k = 0; k < 8; ++k) damped(k, k) += lambda * std::max(a(k, k), 1e-12);
      const Vec8 delta = -damped.ldlt().solve(b);
      if (!delta.allFinite()) break;
      Pose4 q = p;
      q.yaw += delta(0), q.pitch += delta(1), q.roll += delta(2);
      if (!hold_f) q.f = std::clamp(p.f + delta(3), 0.8 * p.f, 1.25 * p.f);
      if (fit_k1) q.k1 = std::clamp(p.k1 + delta(7), -0.5, 0.5);
      Eigen::Vector3d next = step;
      for (int k = 0; k < 3; ++k)
        if (free_axes(k) != 0.0) next(k) = std::clamp(offset_enu_m(k) + step(k) + delta(4 + k), -limit(k), limit(k)) - offset_enu_m(k);
      if (objective(q, next) < before) {
        p = q, step = next, improved = true;
        lambda = std::max(1e-6, lambda / 30.0);  // the loop's *10 follows
      }
    }
    if (!improved) break;
  }
  accumulate();  // the statistics and the information at the result
  const double misfit = expected_in > 0.0 ? chi2_in / expected_in : 1.0;
  const double hfov_deg = HfovFromFocalDeg(p.f, width);
  // Independent samples: the columns on one DEM cell (post spacing over
  // distance, at least the bin step) share its error, so a column counts
  // as the share of a cell it spans (the covariance of Register's sigmas
  // counts bins; near terrain on a coarse DEM is fewer samples than it looks).
  double independent = 0.0;
  {
    const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
    const double span_rad = DegToRad(hfov_deg) / cols.size();
    for (const Column& c : cols) {
      double xn, yn;
      match_detail::Undistorted(c, p.f, p.k1, xn, yn);
      const Eigen::Vector3d d = m.transpose() * Eigen::Vector3d(xn, yn, 1.0);
      const double az = std::atan2(d.x(), d.y());
      const double spacing = lookup.PostSpacingM(az), dist = lookup.DistanceM(az);
      const double cell = std::max(step_rad, std::isfinite(spacing) && dist > 0.0 ? spacing / dist : 0.0);
      independent += std::min(1.0, span_rad / cell);
    }
  }
  const double effective = std::clamp(independent / cols.size(), 1e-3, 1.0);
  Mat8 info = a_data * (effective / std::max(1.0, misfit));
  for (int k = 0; k < 3; ++k) info(4 + k, 4 + k) += inv_var(k);
  if (hold_f) info(3, 3) += 1.0;
  if (fit_k1)
    info(7, 7) += k1_inv_var;
  else
    info.row(7).setZero(), info.col(7).setZero(), info(7, 7) = 1.0;
  out.covariance = Mat7(info.inverse().topLeftCorner<7, 7>());  // k1 marginalised
  if (hold_f) out.covariance.row(3).setZero(), out.covariance.col(3).setZero();
  out.pose = p.ToPose();
  out.focal_px = p.f;
  out.k1 = p.k1;
  out.step_enu_m = step;
  out.cost = cost;
  out.inlier_share = inliers;
  return out;
}

}  // namespace horizonreg
