// SPDX-License-Identifier: MIT
#include "pipeline/position_check.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include "match/fit.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

void PositionCheckOptions::Check() const {
  if (!(first_step_m > 0.0)) ThrowField("PositionCheckOptions::first_step_m", first_step_m, "> 0");
  if (!(far_ring_m >= 0.0)) ThrowField("PositionCheckOptions::far_ring_m", far_ring_m, ">= 0 (0: none)");
  if (!(min_step_m > 0.0 && min_step_m <= first_step_m))
    ThrowField("PositionCheckOptions::min_step_m", min_step_m, "0 < min_step_m <= first_step_m");
  if (directions < 3 || directions > 64) ThrowField("PositionCheckOptions::directions", directions, "3..64");
  if (!(max_offset_m >= first_step_m)) ThrowField("PositionCheckOptions::max_offset_m", max_offset_m, ">= first_step_m");
  if (candidates < 2) ThrowField("PositionCheckOptions::candidates", candidates, ">= 2");
  if (refined_candidates < 2) ThrowField("PositionCheckOptions::refined_candidates", refined_candidates, ">= 2");
  if (max_horizons < directions) ThrowField("PositionCheckOptions::max_horizons", max_horizons, ">= directions");
  if (!(max_cost_ratio > 0.0 && max_cost_ratio < 1.0))
    ThrowField("PositionCheckOptions::max_cost_ratio", max_cost_ratio, "0 < ratio < 1");
  if (!(max_cost_ratio_ridges >= max_cost_ratio && max_cost_ratio_ridges < 1.0))
    ThrowField("PositionCheckOptions::max_cost_ratio_ridges", max_cost_ratio_ridges, "max_cost_ratio <= ratio < 1");
  if (!(wide_radius_ridges_m >= 0.0))
    ThrowField("PositionCheckOptions::wide_radius_ridges_m", wide_radius_ridges_m, ">= 0");
  if (!(lens_departure >= 0.0)) ThrowField("PositionCheckOptions::lens_departure", lens_departure, ">= 0");
  if (!(lens_departure_from >= 0.0 && lens_departure_full > lens_departure_from))
    ThrowField("PositionCheckOptions::lens_departure_full", lens_departure_full, "> lens_departure_from >= 0");
  if (!(min_offset_m >= 0.0)) ThrowField("PositionCheckOptions::min_offset_m", min_offset_m, ">= 0");
  if (!(wide_trigger >= -1.0 && wide_trigger <= 1.0))
    ThrowField("PositionCheckOptions::wide_trigger", wide_trigger, "in [-1, 1] (-1: never)");
  if (!(wide_spacing_m > 0.0)) ThrowField("PositionCheckOptions::wide_spacing_m", wide_spacing_m, "> 0");
  if (!(wide_radius_m >= 0.0)) ThrowField("PositionCheckOptions::wide_radius_m", wide_radius_m, ">= 0 (0: none)");
  if (!(view_margin_deg >= 0.0 && view_margin_deg <= 180.0))
    ThrowField("PositionCheckOptions::view_margin_deg", view_margin_deg, "in [0, 180]");
}

double PositionCheckOptions::MaxCostRatio() const {
  if (ridges_decided) return max_cost_ratio_ridges;
  const double w =
      std::clamp((lens_departure - lens_departure_from) / (lens_departure_full - lens_departure_from), 0.0, 1.0);
  return max_cost_ratio + w * (max_cost_ratio_ridges - max_cost_ratio);
}

double PositionCheck::BearingDeg() const {
  return WrapAzimuthDeg(RadToDeg(std::atan2(best_offset_en_m.x(), best_offset_en_m.y())));
}

double PositionCheck::AzimuthShiftDeg() const { return AngDiffDeg(best_pose.azimuth_deg, given_pose.azimuth_deg); }

namespace {

// A move must lower the cost by this share to be taken (not rounding noise).
constexpr double kMinGain = 1e-3;
// The wide look's grid is fitted this many places at a time (a multiple of
// the 2 threads), nearest first, until one passes the limit.
constexpr size_t kWideChunk = 16;

// Outside the computed sector the horizon is held at the sector's edge
// values: no extrema (no hypotheses) there, and a pose driven outside fits
// a flat line, not NaN.
void HoldSectorEdges(HorizonProfile& h) {
  const int n = h.size();
  int first = -1;
  for (int i = 0; i < n; ++i)
    if (std::isfinite(h.elevation_deg[i]) && !std::isfinite(h.elevation_deg[(i + n - 1) % n])) first = i;
  if (first < 0) {  // all finite, or none
    for (double& e : h.elevation_deg)
      if (!std::isfinite(e)) e = -90.0;
    return;
  }
  // Walk once around from a run's start, carrying the last finite value
  // forward over each gap's first half and the next run's first value back
  // over its second half.
  for (int k = 0; k < n;) {
    const int i = (first + k) % n;
    if (std::isfinite(h.elevation_deg[i])) {
      ++k;
      continue;
    }
    int len = 0;
    while (len < n && !std::isfinite(h.elevation_deg[(i + len) % n])) ++len;
    const double before = h.elevation_deg[(i + n - 1) % n], after = h.elevation_deg[(i + len) % n];
    for (int j = 0; j < len; ++j) h.elevation_deg[(i + j) % n] = j < len / 2 ? before : after;
    k += len;
  }
}

}  // namespace

PositionCheck CheckPositionConsistency(const Site& site, const HorizonProfile& horizon, const Skyline& skyline,
                                       const Registration& reg, const RegistrationOptions& options,
                                       const PositionCheckOptions& co, ThreadPool* pool) {
  co.Check();
  const auto t0 = std::chrono::steady_clock::now();
  const bool strict = co.ridges_decided || co.lens_departure > co.lens_departure_from;
  const double max_cost_ratio = co.MaxCostRatio();
  const double wide_radius = strict ? std::max(co.wide_radius_m, co.wide_radius_ridges_m) : co.wide_radius_m;
  PositionCheck out;
  auto finish = [&] {
    out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return out;
  };
  if (!(reg.focal_px > 0.0) || horizon.size() < 8) return finish();

  // The view's sector (the opening angle's half and a margin each side),
  // and horizons as far as the view's own reaches (+30%, +3 km).
  HorizonOptions ho = site.horizon_options();
  ho.azimuth_step_deg = horizon.azimuth_step_deg;
  ho.num_threads = 1;
  ho.pool = nullptr;
  ho.sector_center_deg = reg.pose.azimuth_deg;
  ho.sector_half_width_deg =
      std::min(180.0, 0.5 * HfovFromFocalDeg(reg.focal_px, skyline.width) + co.view_margin_deg);
  double view_distance = 0.0;
  for (int i = 0; i < horizon.size(); ++i)
    if (ho.InSector(horizon.AzimuthDeg(i)) && std::isfinite(horizon.distance_m[i]))
      view_distance = std::max(view_distance, horizon.distance_m[i]);
  ho.max_distance_m = std::min(ho.max_distance_m, 1.3 * view_distance + 3000.0);
  if (!(ho.max_distance_m > ho.min_distance_m)) return finish();
  // Each place searched as the photo was (its opening angles and priors),
  // one thread per place.
  RegistrationOptions ro = options;
  ro.pool = nullptr;
  ro.num_threads = 1;
  ro.search_only = true;
  ro.narrow_window_restarts = false;  // places compared alike, at the cost of one start each
  ro.bound_search_focal = false;      // and alike without the projected line search (a fifth of the time)
  // The azimuth scan of a plain skyline (RegistrationOptions::
  // scan_plain_skylines) only where the registration needed it: a place
  // whose sector holds fewer pairs of peaks and dips would otherwise be
  // searched more thoroughly than the given position (a cool-toned copy of
  // AK01b_20100525, registered 0.08 deg off by the pairs, was refused for a
  // place 3.7 km away that the scan alone fitted 12% better).
  ro.scan_plain_skylines = options.scan_plain_skylines && reg.scanned_hypotheses > 0;
  // Fewer hypotheses refined than the registration's own search: the best
  // place of the probes is the same with 2 of 4 as with 8 of 8 (ratios
  // unchanged on the 23 probe cases), in 55 ms instead of 95.
  ro.candidates = std::min(ro.candidates, co.candidates);
  ro.refined_candidates = std::min({ro.refined_candidates, co.refined_candidates, ro.candidates});
  // Under the DEM's flattening as the registration measured it (a view
  // rendered from the DEM itself is held to it tightly; a photo over a
  // coarse DEM keeps its tolerance): the tolerance of the model as given
  // let a rendered view fit 19% better from 1 km away (rainier_00), the
  // measured one 9%.
  if (std::isfinite(reg.dem.flattening_scale))
    ro.dem_error = match_detail::ScaledModel(ro.dem_error, reg.dem.flattening_scale);

  const LocalFrame frame(horizon.observer);
  const bool altitude_given = site.options().alt_m.has_value();
  const double given_eye = horizon.observer.height_m;
  const double given_agl =
      std::isfinite(horizon.ground_height_m) ? std::max(0.1, given_eye - horizon.ground_height_m) : kDefaultEyeHeightM;

  struct Place {
    Eigen::Vector2d en{0.0, 0.0};
    double cost = INFINITY;
    CameraPose pose{};  // the best pose there
    std::shared_ptr<const std::vector<Eigen::Vector3d>> points;  // its horizon's (HorizonPoints): hints
  };
  // The DEM the places' horizons sweep (the wide look's indexed copy).
  const TerrainWindow* sweep_window = &site.window();
  std::optional<TerrainWindow> indexed;
  const auto given_points = std::make_shared<const std::vector<Eigen::Vector3d>>(HorizonPoints(horizon));
  // Every place fitted so far: the pattern's rings come back to places
  // already fitted (the centre it left, the first rings' places), which
  // are taken from here instead of computed again; their horizons hint
  // their neighbours'.
  std::vector<Place> fitted;
  // The horizon at a place: the sector of the given one (the same bins,
  // within the reach) or computed.
  auto horizon_at = [&](const Eigen::Vector2d& en) -> std::optional<HorizonProfile> {
    if (en.isZero()) {
      HorizonProfile h = horizon;
      for (int i = 0; i < h.size(); ++i)
        if (!ho.InSector(h.AzimuthDeg(i)))
          h.elevation_deg[i] = h.distance_m[i] = h.lat_deg[i] = h.lon_deg[i] = h.height_m[i] = h.post_spacing_m[i] =
              h.relief_slope[i] = NAN;
      return h;
    }
    GeodeticPoint g = frame.GeodeticFromEnu(Eigen::Vector3d(en.x(), en.y(), 0.0));
    const std::optional<double> ground = sweep_window->HeightAt(g.lat_deg, g.lon_deg);
    if (!ground) return std::nullopt;
    g.height_m = altitude_given ? std::max(given_eye, *ground + kDefaultEyeHeightM) : *ground + given_agl;
    // The horizon of the nearest place fitted before (or the given one),
    // seen from here, culls the terrain below it sooner.
    const std::vector<Eigen::Vector3d>* source = given_points.get();
    double nearest = en.norm();
    for (const Place& f : fitted)
      if (f.points && (f.en - en).norm() < nearest) nearest = (f.en - en).norm(), source = f.points.get();
    return ComputeHorizonNear(*sweep_window, g, ho, *source);
  };
  // The best pose's cost at each place (the search's, under the DEM error
  // model as given: comparable between places).
  auto fit = [&](Place& p) {
    std::optional<HorizonProfile> h = horizon_at(p.en);
    if (!h) return;
    p.points = std::make_shared<const std::vector<Eigen::Vector3d>>(HorizonPoints(*h));
    HoldSectorEdges(*h);
    const Registration r = Register(skyline, *h, ro);
    if (r.candidates.empty()) return;
    p.cost = r.candidates[0].cost;
    p.pose = r.candidates[0].pose;
  };
  int visited = 0;  // places the pattern has visited, fitted before or not: what the budget counts
  auto fit_all = [&](std::vector<Place>& places) {
    visited += static_cast<int>(places.size());
    std::vector<size_t> todo;
    for (size_t i = 0; i < places.size(); ++i) {
      const auto seen = std::find_if(fitted.begin(), fitted.end(),
                                     [&](const Place& f) { return (f.en - places[i].en).norm() < 1.0; });
      if (seen != fitted.end())
        places[i] = *seen;
      else
        todo.push_back(i);
    }
    auto one = [&](size_t k, int) { fit(places[todo[k]]); };
    if (pool)
      pool->ParallelFor(todo.size(), one);
    else
      for (size_t k = 0; k < todo.size(); ++k) one(k, 0);
    for (size_t i : todo) fitted.push_back(places[i]);
    out.horizons += static_cast<int>(todo.size());
  };
  auto ring = [&](const Eigen::Vector2d& from, double radius, std::vector<Place>& places) {
    for (int k = 0; k < co.directions; ++k) {
      const double a = 2.0 * kPi * k / co.directions;
      const Eigen::Vector2d en = from + radius * Eigen::Vector2d(std::sin(a), std::cos(a));
      if (en.norm() <= co.max_offset_m) places.push_back({en, INFINITY, CameraPose{}, nullptr});
    }
  };

  // The given position (searched on the same sector) and the first ring.
  std::vector<Place> places{Place{}};
  ring(Eigen::Vector2d::Zero(), co.first_step_m, places);
  fit_all(places);
  const Place given = places[0];
  if (!std::isfinite(given.cost) || !(given.cost > 0.0)) return finish();
  Place center = given;
  places.erase(places.begin());
  // The far ring only where the cost falls somewhere on the first: a given
  // position that no place 1 km away beats lies at the bottom of its bowl
  // (every false registration of the ring probes fell at 1 km already), and
  // a true one is spared half the horizons.
  const bool falls = std::any_of(places.begin(), places.end(),
                                 [&](const Place& p) { return p.cost < (1.0 - kMinGain) * given.cost; });
  if (falls && co.far_ring_m > co.first_step_m) {
    std::vector<Place> far;
    ring(Eigen::Vector2d::Zero(), co.far_ring_m, far);
    fit_all(far);
    places.insert(places.end(), far.begin(), far.end());
  }
  // A place that fits clearly better, far enough away: the registration is
  // refused once the pattern's centre is one.
  auto passes = [&](const Place& p) {
    return p.cost < max_cost_ratio * given.cost && p.en.norm() >= co.min_offset_m;
  };
  auto refused = [&] { return passes(center); };
  // The pattern: from the best of `places` when it beats the centre, else
  // finer steps around the centre, down to `min_step` (only once the search
  // has moved away from the given position), within `budget` places.
  auto walk = [&](double step, double min_step, int budget) {
    while (!refused()) {
      const Place* best = nullptr;
      for (const Place& p : places)
        if (std::isfinite(p.cost) && (!best || p.cost < best->cost)) best = &p;
      if (best && best->cost < (1.0 - kMinGain) * center.cost) {
        center = *best;
      } else {
        step *= 0.5;
        if (center.en.isZero() || step < min_step * (1.0 - 1e-9)) break;
      }
      places.clear();
      ring(center.en, step, places);
      // The budget counts every place visited, those taken from `fitted`
      // too: they save time but change no decision.
      if (places.empty() || visited + static_cast<int>(places.size()) > budget) break;
      fit_all(places);
    }
  };
  walk(co.first_step_m, co.min_step_m, co.max_horizons);
  // The wide look. A given position that is not clearly the bottom of a
  // bowl (some place of the first ring fits within `wide_trigger` of its
  // cost, or better) and was not refused may still lie 2-4 km from the true
  // position, whose bowl is only about 1 km across on a 100 m DEM: real
  // photos given no altitude, the eye 2 m over a valley 3 km from the
  // station, sat in a shallow bowl of their own (first ring 1.01-1.012)
  // while the truth fit 17-25% better with nothing between; from the true
  // positions no place within 4 km fits better (the real photos' cost
  // maps), and 14 of 36 true registrations have such a shallow first ring
  // (0.93-1.03; they pay the grid's time, about 1.1-1.5 s). So a hexagonal
  // grid of places over the disc, and the pattern again from its best.
  // Given no altitude and a known opening angle, the look is taken whatever
  // the first ring (PositionCheckOptions::wide_when_unpinned).
  const bool unpinned = co.wide_when_unpinned && !altitude_given && options.OpeningAngleKnown();
  const bool shallow = unpinned || std::any_of(fitted.begin(), fitted.end(), [&](const Place& p) {
    return p.en.norm() > 1.0 && p.en.norm() <= co.first_step_m + 1.0 && p.cost < (1.0 + co.wide_trigger) * given.cost;
  });
  if (!refused() && shallow && wide_radius > co.first_step_m) {
    if ((indexed = WithPostTrig(site.window()))) sweep_window = &*indexed;
    places.clear();
    const double s = co.wide_spacing_m, row = s * std::sqrt(0.75);
    const int rows = static_cast<int>(std::ceil(wide_radius / row));
    for (int r = -rows; r <= rows; ++r)
      for (int c = -rows - 1; c <= rows + 1; ++c) {
        const Eigen::Vector2d en((c + 0.5 * (r & 1)) * s, r * row);
        if (en.norm() > co.first_step_m + 0.5 * s && en.norm() <= wide_radius && en.norm() <= co.max_offset_m)
          places.push_back({en, INFINITY, CameraPose{}, nullptr});
      }
    // Nearest first, a few places at a time, until one passes the limit:
    // refused then whatever the rest would show (the pattern only goes
    // lower), and a wrong position is answered sooner.
    std::stable_sort(places.begin(), places.end(),
                     [](const Place& a, const Place& b) { return a.en.norm() < b.en.norm(); });
    const int budget = visited + static_cast<int>(places.size()) + 4 * co.directions;
    std::vector<Place> grid;
    for (size_t first = 0; first < places.size();) {
      std::vector<Place> chunk(places.begin() + first,
                               places.begin() + std::min(places.size(), first + kWideChunk));
      first += chunk.size();
      fit_all(chunk);
      grid.insert(grid.end(), chunk.begin(), chunk.end());
      if (std::any_of(chunk.begin(), chunk.end(), passes)) break;
    }
    out.wide_places = static_cast<int>(grid.size());
    places = std::move(grid);
    walk(0.5 * s, 0.5 * s, budget);
  }
  out.cost_ratio = center.cost / given.cost;
  out.best_offset_en_m = center.en;
  out.given_pose = given.pose;
  out.best_pose = center.pose;
  if (refused()) {
    out.consistent = false;
    const bool only_strict = !(center.cost < co.max_cost_ratio * given.cost);
    // The ridges' limit doubts the pose; the lens's names the position.
    out.only_ridges_limit = only_strict && co.ridges_decided;
    out.only_lens_limit = only_strict && !co.ridges_decided;
    std::ostringstream m;
    m << std::fixed << std::setprecision(1) << "the skyline fits clearly better from " << out.OffsetM() / 1000.0
      << " km away at bearing " << std::setprecision(0) << out.BearingDeg() << " deg (cost ratio "
      << std::setprecision(2) << out.cost_ratio << "): the given camera position looks wrong";
    if (out.only_lens_limit)
      m << " (the opening angle fitted here departs from the EXIF's, so its position must fit within "
        << std::setprecision(2) << max_cost_ratio << ")";
    else if (out.only_ridges_limit)
      m << ", or the pose the inner ridges chose is (its position must fit within " << std::setprecision(2)
        << max_cost_ratio << ")";
    out.message = m.str();
  }
  return finish();
}

}  // namespace horizonreg
