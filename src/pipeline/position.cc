// SPDX-License-Identifier: MIT
#include "pipeline/position.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include "match/position_fit.h"
#include "pipeline/site.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

void PositionOptions::Check() const {
  if (!(horizontal_sigma_m > 0.0 && horizontal_sigma_m <= 10'000.0))
    ThrowField("PositionOptions::horizontal_sigma_m", horizontal_sigma_m, "in (0, 10000] metres");
  if (!(vertical_sigma_m > 0.0 && vertical_sigma_m <= 10'000.0))
    ThrowField("PositionOptions::vertical_sigma_m", vertical_sigma_m, "in (0, 10000] metres");
  if (max_horizons < 1) ThrowField("PositionOptions::max_horizons", max_horizons, ">= 1");
  if (!(converged_m > 0.0)) ThrowField("PositionOptions::converged_m", converged_m, "> 0");
  if (!(observable_ratio > 0.0 && observable_ratio <= 1.0))
    ThrowField("PositionOptions::observable_ratio", observable_ratio, "in (0, 1]");
}

PositionOptions DefaultPositionOptions(const std::string& position_source, bool exif_altitude,
                                       std::optional<double> horizontal_sigma_m) {
  PositionOptions o;
  o.horizontal_sigma_m = position_source == "arguments" ? 15.0 : 10.0;
  o.vertical_sigma_m = exif_altitude ? 20.0 : 10.0;
  if (horizontal_sigma_m) o.horizontal_sigma_m = *horizontal_sigma_m;
  return o;
}

namespace {
double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

Eigen::Vector3d PositionSearchStart(const Site& site) {
  const GeodeticPoint& eye = site.observer();
  const std::optional<double> ground = site.window().HeightAt(eye.lat_deg, eye.lon_deg);
  if (ground && eye.height_m < *ground + 0.5) return Eigen::Vector3d(0.0, 0.0, *ground + kDefaultEyeHeightM - eye.height_m);
  return Eigen::Vector3d::Zero();
}

PositionEstimate RefinePosition(const Site& site, const Skyline& skyline, const Registration& first,
                                const RegistrationOptions& options, const PositionOptions& po, ThreadPool* pool,
                                const Eigen::Vector3d& start_offset_enu_m, const HorizonProfile* start_horizon) {
  po.Check();
  options.Check();
  const auto t0 = std::chrono::steady_clock::now();
  PositionEstimate est;
  est.given = est.observer = site.observer();
  est.prior_sigma_enu_m = Eigen::Vector3d(po.horizontal_sigma_m, po.horizontal_sigma_m, po.vertical_sigma_m);
  est.sigma_enu_m = est.prior_sigma_enu_m;
  est.horizon = site.horizon();
  if (!(first.focal_px > 0.0)) {
    est.message = "no pose to refine the position from: the given position is kept";
    est.ms = MsSince(t0);
    return est;
  }
  const LocalFrame frame(est.given);
  HorizonOptions ho = site.horizon_options();
  ho.pool = pool;
  const bool fix_focal = options.known_intrinsics.has_value();
  // k1 as the registration fitted it is a start, not a given: fitted at a
  // position tens of metres off, it absorbs the parallax the position
  // makes (cascades_02 from 30 m and 20 m off: k1 +0.14 with the focal
  // length 3% short; at the truth -0.01), and held there it kept the
  // search from the truth. So it is fitted with the position when the
  // registration fitted it.
  double k1 = 0.0;
  if (first.distortion_estimated && !first.intrinsics.distortion.k().empty()) k1 = first.intrinsics.distortion.k()[0];
  const bool free_k1 = first.distortion_estimated;
  const double scale = std::isfinite(first.dem.flattening_scale) ? first.dem.flattening_scale : 1.0;

  // The DEM error model's position term: in the steps, the size of the
  // last accepted step (from the prior at first), so that a far-off start
  // does not let near columns, still many pixels off, dominate; in the
  // judging of a step and the final covariance, 1 m.
  auto with_term = [&](const Eigen::Vector3d& term) {
    RegistrationOptions o = options;
    o.dem_error.position_sigma_m = std::max(1.0, std::hypot(term(0), term(1)) / std::sqrt(2.0));
    o.dem_error.height_sigma_m = std::max(1.0, term(2));
    return o;
  };
  const RegistrationOptions judge = with_term(Eigen::Vector3d::Zero());
  const Eigen::Vector3d inv_sigma = est.prior_sigma_enu_m.cwiseInverse();
  const Eigen::Vector3d prior = est.prior_sigma_enu_m;
  // The posterior's negative log (times 2) at a position, the orientation refitted there.
  auto total = [&](const PoseAndPositionFit& f, const Eigen::Vector3d& at) {
    return f.cost * f.columns + at.cwiseProduct(inv_sigma).squaredNorm();
  };
  struct Search {
    Eigen::Vector3d offset;
    HorizonProfile horizon;
    PoseAndPositionFit now;  // orientation fitted at offset (position held)
    PoseAndPositionFit fit;  // the joint fit there: the covariance
  };
  // Moves the axes in `free` (1 free, 0 held) from `from`, whose horizon is
  // `h`, with at most `budget` new horizons.
  auto search = [&](const Eigen::Vector3d& free, const Eigen::Vector3d& from, HorizonProfile h, const CameraPose& pose,
                    double focal, double start_k1, int budget) {
    Search out{from, std::move(h), {}, {}};
    const Eigen::Vector3d held = Eigen::Vector3d::Zero();
    out.now = FitPoseAndPosition(skyline, out.horizon, pose, focal, start_k1, free_k1, fix_focal, out.offset, prior,
                                 judge, scale, 6, held);
    Eigen::Vector3d term = prior;
    // Proposals under the annealed model with a weak prior (the inflated
    // noise weakens the data as much); once they stop, under the final
    // model with the whole prior (the posterior's own Gauss-Newton).
    bool polishing = false;
    int used = 0;
    while (used < budget) {
      const PoseAndPositionFit fit = FitPoseAndPosition(
          skyline, out.horizon, out.now.pose, out.now.focal_px, out.now.k1, free_k1, fix_focal, out.offset, prior,
          polishing ? judge : with_term(term), scale, 6, free, polishing ? 1.0 : 0.1);
      Eigen::Vector3d step = fit.step_enu_m;
      bool accepted = false;
      // The step is taken only when the exact horizon there fits better
      // (halved once when it does not): the horizon is linear in the move
      // only for small moves.
      for (int tries = 0; tries < 2 && step.norm() >= po.converged_m && used < budget && !accepted;
           ++tries, step *= 0.5) {
        HorizonProfile trial =
            ComputeHorizonNear(site.window(), frame.GeodeticFromEnu(out.offset + step), ho, out.horizon);
        ++used;
        const PoseAndPositionFit judged =
            FitPoseAndPosition(skyline, trial, fit.pose, fit.focal_px, fit.k1, free_k1, fix_focal, out.offset + step,
                               prior, judge, scale, 6, held);
        if (total(judged, out.offset + step) < total(out.now, out.offset)) {
          out.offset += step;
          out.horizon = std::move(trial);
          out.now = judged;
          term = step.cwiseAbs();
          accepted = true;
        }
      }
      if (!accepted) {
        if (polishing) break;
        polishing = true;
      }
    }
    est.horizons += used;
    // The information at the estimate (its step is not taken: not judged),
    // with k1 held where the search left it (as the registration's was
    // before): marginalised, k1 shares the near terrain's curvature with the
    // eye height, and of the dev scenes' 60 refinements 34 heights stay
    // observable instead of 37 (within 3 m: 30 instead of 32).
    out.fit = FitPoseAndPosition(skyline, out.horizon, out.now.pose, out.now.focal_px, out.now.k1, false, fix_focal,
                                 out.offset, prior, judge, scale, 6, free);
    return out;
  };
  HorizonProfile start = start_horizon ? *start_horizon : site.horizon();
  if (!start_horizon && start_offset_enu_m != Eigen::Vector3d::Zero())
    start = ComputeHorizonNear(site.window(), frame.GeodeticFromEnu(start_offset_enu_m), ho, site.horizon()),
    ++est.horizons;
  // All three axes free first; then, when only some are observable, those
  // alone from the start (a weak axis left free trades against the
  // orientation and drags the others: near terrain straight ahead tells the
  // distance to it, not the sideways position).
  // The height first, on a coarse scan of exact horizons (+-1.5 prior
  // sigmas, not below the ground): it is the best-observed axis, and from a
  // start tens of metres off a horizontal move can mimic it (moving towards
  // near terrain raises it as lowering the eye does), a local minimum.
  Eigen::Vector3d from = start_offset_enu_m;
  CameraPose from_pose = first.pose;
  double from_focal = first.focal_px, from_k1 = k1;
  if (po.height_scan) {
    const Eigen::Vector3d held = Eigen::Vector3d::Zero();
    PoseAndPositionFit best = FitPoseAndPosition(skyline, start, first.pose, first.focal_px, k1, free_k1, fix_focal,
                                                 from, prior, judge, scale, 6, held);
    double best_total = total(best, from);
    const std::optional<double> ground = site.window().HeightAt(est.given.lat_deg, est.given.lon_deg);
    for (double k : {-1.5, 1.5}) {
      const Eigen::Vector3d at = start_offset_enu_m + Eigen::Vector3d(0.0, 0.0, k * prior(2));
      if (ground && est.given.height_m + at.z() < *ground + 0.5) continue;
      HorizonProfile h = ComputeHorizonNear(site.window(), frame.GeodeticFromEnu(at), ho, start);
      ++est.horizons;
      const PoseAndPositionFit f = FitPoseAndPosition(skyline, h, first.pose, first.focal_px, k1, free_k1, fix_focal,
                                                      at, prior, judge, scale, 6, held);
      if (total(f, at) < best_total) {
        best_total = total(f, at), best = f, from = at, start = std::move(h);
        from_pose = f.pose, from_focal = f.focal_px, from_k1 = f.k1;
      }
    }
  }
  Search s = search(Eigen::Vector3d::Ones(), from, start, from_pose, from_focal, from_k1, po.max_horizons);
  auto sigmas = [&](const Search& x) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v(k) = std::sqrt(std::max(0.0, x.fit.covariance(4 + k, 4 + k)));
    return v;
  };
  Eigen::Vector3d sigma = sigmas(s), free = Eigen::Vector3d::Zero();
  int observable_axes = 0;
  for (int k = 0; k < 3; ++k) {
    est.observable_axis[k] = sigma(k) < po.observable_ratio * prior(k);
    observable_axes += est.observable_axis[k];
    free(k) = est.observable_axis[k] ? 1.0 : 0.0;
  }
  if (observable_axes > 0 && observable_axes < 3 && po.hold_weak_axes) {
    // Restart from the start with the weak axes held there.
    s = search(free, from, start, from_pose, from_focal, from_k1, po.max_horizons);
    sigma = sigmas(s);
    for (int k = 0; k < 3; ++k)
      if (free(k) != 0.0) est.observable_axis[k] = sigma(k) < po.observable_ratio * prior(k);
  }
  const Eigen::Vector3d offset = s.offset;
  const PoseAndPositionFit& fit = s.fit;
  HorizonProfile horizon = std::move(s.horizon);
  observable_axes = est.observable_axis[0] + est.observable_axis[1] + est.observable_axis[2];
  std::ostringstream m;
  m.precision(3);
  if (observable_axes == 0) {
    m << "position not observable (the horizon seen is too far for the prior of " << po.horizontal_sigma_m << " m, "
      << po.vertical_sigma_m << " m up): the given position is kept";
    est.message = m.str();
    est.ms = MsSince(t0);
    return est;
  }
  est.observable = observable_axes == 3;
  est.offset_enu_m = offset;
  est.sigma_enu_m = sigma;
  est.observer = frame.GeodeticFromEnu(offset);
  est.horizon = std::move(horizon);
  const auto& c = fit.covariance;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j) {
      const double v = c(4 + k, 4 + k) * c(j, j);
      est.correlation(k, j) = v > 0.0 ? c(4 + k, j) / std::sqrt(v) : 0.0;
    }
  est.azimuth_sigma_deg = RadToDeg(std::sqrt(std::max(0.0, c(0, 0))));
  est.pitch_sigma_deg = RadToDeg(std::sqrt(std::max(0.0, c(1, 1))));
  m << "position refined by " << offset.head<2>().norm() << " m horizontally and " << offset(2) << " m up";
  if (!est.observable) {
    m << " (observable:";
    const char* names[3] = {" east", " north", " up"};
    for (int k = 0; k < 3; ++k)
      if (est.observable_axis[k]) m << names[k];
    m << ")";
  }
  est.message = m.str();
  est.ms = MsSince(t0);
  return est;
}

}  // namespace horizonreg
