// SPDX-License-Identifier: MIT
#include "pipeline/locate.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <sstream>

#include "geo/conventions.h"
#include "geo/geodesy.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace locate_detail {

Profile SkylineProfile(const Skyline& skyline, double hfov_deg, double pitch_deg, double per_deg) {
  Profile p;
  p.hfov_deg = hfov_deg;
  p.pitch_deg = pitch_deg;
  const double w = skyline.width, h = skyline.height;
  const double f = 0.5 * w / std::tan(DegToRad(0.5 * hfov_deg));
  const double cx = 0.5 * w, cy = 0.5 * h;
  const double sp = std::sin(DegToRad(pitch_deg)), cp = std::cos(DegToRad(pitch_deg));
  const int n = static_cast<int>(std::floor(hfov_deg * per_deg));
  for (int k = 0; k < n; ++k) {
    const double x = cx + f * std::tan(DegToRad(-0.5 * hfov_deg + (k + 0.5) / per_deg));
    // The median of the columns within +-1 of x (a lone misread column does not count).
    double ys[3];
    int m = 0;
    for (int c = static_cast<int>(std::floor(x)) - 1; c <= static_cast<int>(std::floor(x)) + 1; ++c) {
      if (c < 0 || c >= skyline.width) continue;
      if (const double y = skyline.MatchY(c); std::isfinite(y)) ys[m++] = y;
    }
    if (m == 0) {
      p.offset_deg.push_back(RadToDeg(std::atan2(x - cx, f * cp)));
      p.elevation_deg.push_back(NAN);
      continue;
    }
    const double y = m == 3 ? std::max(std::min(ys[0], ys[1]), std::min(std::max(ys[0], ys[1]), ys[2])) : ys[0];
    // The pixel's ray for a camera pitched by pitch_deg (roll 0): right x - cx,
    // up along the tilted axis cy - y, forward f.
    const double up = f * sp + (cy - y) * cp, ahead = f * cp - (cy - y) * sp, right = x - cx;
    p.offset_deg.push_back(RadToDeg(std::atan2(right, ahead)));
    p.elevation_deg.push_back(RadToDeg(std::atan2(up, std::hypot(right, ahead))));
  }
  return p;
}

std::pair<double, double> MatchProfile(const Profile& profile, const std::vector<double>& horizon, double hstep,
                                       double step_deg, double around_deg, double within_deg) {
  constexpr double kTruncDeg2 = 1.0;       // residuals beyond 1 deg count as 1 deg
  constexpr double kMaxSlope = 0.18;        // |roll| up to ~10 deg
  std::vector<double> off, el;
  for (size_t k = 0; k < profile.offset_deg.size(); ++k)
    if (std::isfinite(profile.elevation_deg[k])) off.push_back(profile.offset_deg[k]), el.push_back(profile.elevation_deg[k]);
  const size_t n = off.size();
  if (n < 4 || n < 0.6 * profile.offset_deg.size() || horizon.empty())
    return {std::numeric_limits<double>::infinity(), 0.0};
  const int bins = static_cast<int>(horizon.size());
  // An azimuth's bin and its share of the way to the next; the horizon there.
  auto split = [&](double az, int& i0, double& t) {
    double u = az / hstep;
    u -= bins * std::floor(u / bins);
    i0 = static_cast<int>(u) % bins;
    t = u - std::floor(u);
  };
  auto between = [&](int i0, double t) { return horizon[i0] * (1 - t) + horizon[i0 + 1 == bins ? 0 : i0 + 1] * t; };
  std::vector<double> tmp(n);
  double best = std::numeric_limits<double>::infinity(), best_az = 0.0;
  const bool window = within_deg < 180.0;
  const int steps = window ? 2 * static_cast<int>(std::ceil(within_deg / step_deg)) + 1
                           : static_cast<int>(std::lround(360.0 / step_deg));
  const double first = window ? around_deg - step_deg * (steps / 2) : 0.0;
  // Steps of whole bins (the callers' case): each sample's bin and weight
  // are found once, then moved along by the step's bins (a third of the
  // coarse stage's time went to finding them again).
  const double bins_per_step = step_deg / hstep;
  const int shift = static_cast<int>(std::lround(bins_per_step));
  const bool whole = shift >= 1 && std::abs(bins_per_step - shift) < 1e-12 && std::abs(bins * hstep - 360.0) < 1e-6;
  std::vector<int> bin0(whole ? n : 0);
  std::vector<double> weight(whole ? n : 0);
  if (whole) {
    const double az0 = first - 360.0 * std::floor(first / 360.0);
    for (size_t k = 0; k < n; ++k) split(az0 + off[k], bin0[k], weight[k]);
  }
  // The cost at search step s over every stride-th sample (the same
  // estimator on fewer samples): 1 or kScreenStride.
  constexpr size_t kScreenStride = 4;
  std::vector<double> off_screen;
  for (size_t k = 0; k < n; k += kScreenStride) off_screen.push_back(off[k]);
  auto sum_sq = [](const std::vector<double>& v) {
    double sum = 0;
    for (double o : v) sum += o * o;
    return sum;
  };
  const double sxx_all = sum_sq(off), sxx_screen = sum_sq(off_screen);
  std::vector<double> d(n);
  auto cost_at = [&](int s, size_t stride) {
    double az = first + s * step_deg;
    az -= 360.0 * std::floor(az / 360.0);
    const std::vector<double>& o = stride == 1 ? off : off_screen;
    const double sxx = stride == 1 ? sxx_all : sxx_screen;
    const size_t m = o.size();
    const int moved = whole ? static_cast<int>((static_cast<long>(s) * shift) % bins) : 0;
    for (size_t j = 0, k = 0; j < m; ++j, k += stride) {
      if (whole) {
        const int i0 = bin0[k] + moved;
        d[j] = between(i0 >= bins ? i0 - bins : i0, weight[k]) - el[k];
      } else {
        int i0;
        double t;
        split(az + off[k], i0, t);
        d[j] = between(i0, t) - el[k];
      }
    }
    // Pitch: the median difference; roll: the slope of the near ones; pitch again.
    std::copy(d.begin(), d.begin() + m, tmp.begin());
    std::nth_element(tmp.begin(), tmp.begin() + m / 2, tmp.begin() + m);
    double p = tmp[m / 2], q = 0.0;
    double sxy = 0, sx2 = 0;
    for (size_t j = 0; j < m; ++j)
      if (std::abs(d[j] - p) < 2.0) sxy += o[j] * (d[j] - p), sx2 += o[j] * o[j];
    if (sx2 > 0.05 * sxx) q = std::clamp(sxy / sx2, -kMaxSlope, kMaxSlope);
    for (size_t j = 0; j < m; ++j) tmp[j] = d[j] - q * o[j];
    std::nth_element(tmp.begin(), tmp.begin() + m / 2, tmp.begin() + m);
    p = tmp[m / 2];
    double cost = 0;
    for (size_t j = 0; j < m; ++j) {
      const double r = d[j] - q * o[j] - p;
      cost += std::min(r * r, kTruncDeg2);
    }
    return std::pair{cost / m, az};
  };
  // A long search is screened first on every 4th sample; the full cost is
  // taken at the best eighth of the steps (at least 8). A third of the
  // time; the best step is among them wherever the profile's own fit stands
  // out (the shortlist holds its neighbours too).
  std::vector<int> shortlist;
  if (steps >= 64 && n >= 32) {
    std::vector<std::pair<double, int>> screened(steps);
    for (int s = 0; s < steps; ++s) screened[s] = {cost_at(s, kScreenStride).first, s};
    const size_t keep = std::max<size_t>(8, steps / 8);
    std::nth_element(screened.begin(), screened.begin() + keep, screened.end());
    for (size_t i = 0; i < keep; ++i) shortlist.push_back(screened[i].second);
    std::sort(shortlist.begin(), shortlist.end());  // in step order: ties go to the first, as in a full search
  } else {
    for (int s = 0; s < steps; ++s) shortlist.push_back(s);
  }
  for (const int s : shortlist) {
    const auto [cost, az] = cost_at(s, 1);
    if (cost < best) best = cost, best_az = az;
  }
  return {best, best_az};
}

TerrainWindow Coarsen(const TerrainWindow& window, double post_m) {
  TerrainWindow out;
  for (const DemGrid& g : window.grids) {
    const int k = static_cast<int>(std::floor(post_m / std::max(1.0, g.SpacingM())));
    if (k < 2 || g.width < 4 * k || g.height < 4 * k) {
      out.grids.push_back(g);
      continue;
    }
    DemGrid c;
    c.width = (g.width - 1) / k + 1;
    c.height = (g.height - 1) / k + 1;
    c.separable = g.separable;
    c.source = g.source;
    c.height_m.assign(static_cast<size_t>(c.width) * c.height, NAN);
    if (g.separable) {
      c.lat0_deg = g.lat0_deg, c.dlat_deg = g.dlat_deg * k, c.lon0_deg = g.lon0_deg, c.dlon_deg = g.dlon_deg * k;
    } else {
      c.lat_deg.resize(c.height_m.size()), c.lon_deg.resize(c.height_m.size());
    }
    const int half = k / 2;
    for (int r = 0; r < c.height; ++r)
      for (int col = 0; col < c.width; ++col) {
        const int r0 = std::max(0, r * k - half), r1 = std::min(g.height - 1, r * k + half);
        const int c0 = std::max(0, col * k - half), c1 = std::min(g.width - 1, col * k + half);
        double sum = 0.0;
        int count = 0;
        for (int rr = r0; rr <= r1; ++rr)
          for (int cc = c0; cc <= c1; ++cc)
            if (const float v = g.At(cc, rr); std::isfinite(v)) sum += v, ++count;
        const size_t i = static_cast<size_t>(r) * c.width + col;
        c.height_m[i] = count ? static_cast<float>(sum / count) : NAN;
        if (!g.separable) c.lat_deg[i] = g.LatAt(col * k, r * k), c.lon_deg[i] = g.LonAt(col * k, r * k);
      }
    if (!g.separable) c.IndexPositions();
    c.IndexBlocks();
    out.grids.push_back(std::move(c));
  }
  return out;
}

}  // namespace locate_detail

namespace {

using Clock = std::chrono::steady_clock;
// The position error the viewpoints are compared at, metres: tight, so that
// a place is not credited with the tolerance its near terrain would get
// from a loose position (3 m placed alps_05 414 m off and zion_00's
// equal fits 0.32 deg apart; 2 m the first again; 1 m and 0.5 m neither).
constexpr double kPolishSigmaM = 1.0;
constexpr double kAnswerSigmaFloorM = 3.0;  // the answer's registration: at least this position error
constexpr double kRunnerUpCostRatio = 3.0;  // runners-up polished when their profile misfit is within this ratio
constexpr double kEqualFit = 0.15;          // registration misfits within 15% of the best fit as well
constexpr double kRingMisfitRatio = 1.5;    // polished places within this of the least misfit get a ring ...
constexpr int kRingDirections = 12;         // ... of this many places at 0.75 and 1.25 grid steps
constexpr double kRingMinGain = 0.02;       // a ring place must fit this much better to move to it
constexpr int kRingRestarts = 2;
constexpr int kFollowChecks = 2;            // places an answer's refusing position check points to, polished at most
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// A position east_m, north_m from (lat, lon) in its local tangent plane, and
// the horizontal distance between two positions.
GeodeticPoint Offset(double lat, double lon, double east_m, double north_m) {
  const GeodeticPoint p = LocalFrame({lat, lon, 0.0}).GeodeticFromEnu({east_m, north_m, 0.0});
  return {p.lat_deg, p.lon_deg, 0.0};
}
double DistanceM(double lat0, double lon0, double lat1, double lon1) {
  return LocalFrame({lat0, lon0, 0.0}).EnuFromGeodetic({lat1, lon1, 0.0}).head<2>().norm();
}

// A viewpoint's horizon points (HorizonPoints): hints for its neighbours' horizons.
using HintPoints = std::shared_ptr<const std::vector<Eigen::Vector3d>>;

struct Scored {
  double lat = 0, lon = 0, cost = INFINITY, azimuth = 0, hfov = 0, pitch = 0, coarse_cost = INFINITY;
  HintPoints points;  // when kept
};

// The nearest of `places` (with .lat, .lon, .points) that has points, or null.
template <typename Place>
const std::vector<Eigen::Vector3d>* NearestPoints(const std::vector<Place>& places, double lat, double lon) {
  const std::vector<Eigen::Vector3d>* out = nullptr;
  double best = INFINITY;
  for (const Place& p : places)
    if (p.points && DistanceM(lat, lon, p.lat, p.lon) < best)
      best = DistanceM(lat, lon, p.lat, p.lon), out = p.points.get();
  return out;
}

// The opening angles tried: the registration's window in steps of `factor`.
std::vector<double> HfovsToTry(double lo, double hi, double factor) {
  const int n = std::max(1, static_cast<int>(std::ceil(std::log(hi / lo) / std::log(factor))));
  std::vector<double> out;
  for (int i = 0; i < n; ++i) out.push_back(lo * std::pow(hi / lo, (i + 0.5) / n));
  return out;
}

// Pitches tried: the profile's elevations are exact at these, the pitch
// offset fitted on top of them absorbs the rest (at most 2 deg).
constexpr double kPitchesDeg[] = {-12.0, -8.0, -4.0, 0.0, 4.0, 8.0, 12.0};
constexpr double kFinePitchesDeg[] = {-14.0, -12.0, -10.0, -8.0, -6.0, -4.0, -2.0, 0.0,
                                      2.0,   4.0,   6.0,   8.0,   10.0, 12.0, 14.0};

}  // namespace

void LocateOptions::Check() const {
  if (!(std::abs(lat_deg) <= 90.0)) ThrowField("--area latitude", lat_deg, "within [-90, 90]");
  if (!(std::abs(lon_deg) <= 360.0)) ThrowField("--area longitude", lon_deg, "within [-180, 360]");
  if (!(radius_m >= 10.0 && radius_m <= 50'000.0)) ThrowField("--area radius", radius_m, "in [10, 50000] metres");
  if (!(grid_m == 0.0 || (grid_m >= 10.0 && grid_m <= radius_m)))
    ThrowField("LocateOptions::grid_m", grid_m, "0 (automatic) or in [10, radius] metres");
  if (!(coarse_max_distance_m > 0.0)) ThrowField("LocateOptions::coarse_max_distance_m", coarse_max_distance_m, "> 0");
  if (coarse_keep < 1 || register_keep < 1) throw InvalidArgument("LocateOptions: coarse_keep and register_keep >= 1");
  if (!(coarse_post_m > 0.0)) ThrowField("LocateOptions::coarse_post_m", coarse_post_m, "> 0");
  if (!(min_evidence_nats >= 0.0)) ThrowField("LocateOptions::min_evidence_nats", min_evidence_nats, ">= 0");
  if (site.alt_m) throw InvalidArgument("locate: the eye is given as a height above the ground (--agl), not an altitude");
  site.Check();
  photo.Check();
}

LocateResult Locate(const std::vector<std::string>& dem, const cv::Mat& image, const LocateOptions& options,
                    ThreadPool* pool) {
  options.Check();
  // One DEM window for every candidate: the area plus the final horizon distance.
  const auto t0 = Clock::now();
  Terrain terrain(dem);
  terrain.set_max_window_bytes(options.site.max_dem_bytes);
  const GeodeticPoint centre{options.lat_deg, options.lon_deg, 0.0};
  TerrainWindow window = terrain.ReadWindow(centre, options.radius_m + options.site.max_distance_m);
  if (options.site.sea_level_fill) AddSeaLevel(window, centre, options.radius_m + options.site.max_distance_m);
  const double read_ms = MsSince(t0);
  LocateResult out = LocateInWindow(window, image, options, pool);
  out.dem_ms += read_ms;
  return out;
}

LocateResult LocateInWindow(const TerrainWindow& given_window, const cv::Mat& image, const LocateOptions& options,
                            ThreadPool* pool) {
  options.Check();
  using namespace locate_detail;
  LocateResult out;
  const double radius = options.radius_m;
  const double grid = options.grid_m > 0 ? options.grid_m : std::clamp(radius / 30.0, 100.0, 400.0);
  out.grid_m = grid;
  auto t0 = Clock::now();
  // Thousands of horizons sweep the same window: a projected DEM's posts
  // carry their trigonometry (WithPostTrig; the same horizons).
  const std::optional<TerrainWindow> indexed = WithPostTrig(given_window);
  const TerrainWindow& window = indexed ? *indexed : given_window;
  TerrainWindow coarse = Coarsen(window, options.coarse_post_m);
  if (std::optional<TerrainWindow> c = WithPostTrig(coarse)) coarse = std::move(*c);
  out.dem_ms = MsSince(t0);

  // The skyline, once.
  t0 = Clock::now();
  PhotoOptions po = options.photo;
  // The answer's registration keeps the position check's rings but not its
  // wide look: the places within 4 km are what locate itself compared (the
  // look made each real photo's registrations 25-57 s).
  if (po.check_position) po.check_position->wide_radius_m = 0.0;
  if (!po.skyline) po.skyline = ExtractSkyline(image, PhotoSkylineOptions(po));
  const Skyline& skyline = *po.skyline;
  out.skyline_ms = MsSince(t0);
  // The opening angles `register` would search (arguments, EXIF or its default).
  double hfov_lo = po.registration.min_hfov_deg, hfov_hi = po.registration.max_hfov_deg;
  PhotoHfovWindow(po, image.cols, image.rows, hfov_lo, hfov_hi);
  po.position_source = "locate";
  std::vector<Profile> coarse_profiles, fine_profiles;
  for (double pitch : kPitchesDeg)
    for (double h : HfovsToTry(hfov_lo, hfov_hi, 1.12)) coarse_profiles.push_back(SkylineProfile(skyline, h, pitch, 1.0));
  for (double pitch : kFinePitchesDeg)
    for (double h : HfovsToTry(hfov_lo, hfov_hi, 1.04)) fine_profiles.push_back(SkylineProfile(skyline, h, pitch, 2.0));
  const double agl = options.site.agl_m.value_or(kDefaultEyeHeightM);
  // The profiles' fit at a viewpoint: all of them, or (`near` given) those
  // within 4 deg of its pitch, over azimuths within 4 deg of its own.
  // Its horizon hinted by `hint` (HorizonPoints of a neighbour's on `w`),
  // whose own points are kept with `keep`.
  auto score = [&](const TerrainWindow& w, double lat, double lon, double hstep, double max_distance,
                   const std::vector<Profile>& profiles, double az_step, double min_distance = 0.5,
                   const Scored* near = nullptr, const std::vector<Eigen::Vector3d>* hint = nullptr,
                   bool keep = false) {
    Scored s;
    s.lat = lat, s.lon = lon;
    const std::optional<double> ground = window.HeightAt(lat, lon);
    if (!ground) return s;
    HorizonOptions ho;
    ho.azimuth_step_deg = hstep;
    ho.max_distance_m = max_distance;
    ho.min_distance_m = min_distance;
    ho.refraction = options.site.refraction;
    ho.num_threads = 1;
    const GeodeticPoint eye{lat, lon, *ground + agl};
    const HorizonProfile hp = hint ? ComputeHorizonNear(w, eye, ho, *hint) : ComputeHorizon(w, eye, ho);
    if (keep) s.points = std::make_shared<const std::vector<Eigen::Vector3d>>(HorizonPoints(hp));
    for (const Profile& p : profiles) {
      if (near && std::abs(p.pitch_deg - near->pitch) > 4.01) continue;
      const auto [cost, az] = near ? MatchProfile(p, hp.elevation_deg, hstep, az_step, near->azimuth, 4.0)
                                   : MatchProfile(p, hp.elevation_deg, hstep, az_step);
      if (cost < s.cost) s.cost = cost, s.azimuth = az, s.hfov = p.hfov_deg, s.pitch = p.pitch_deg;
    }
    return s;
  };
  // items[i] = fn(items[i]) for every item, on the pool when there is one.
  auto run_all = [&](auto& items, auto&& fn) {
    if (pool) {
      pool->ParallelFor(items.size(), [&](size_t i, int) { items[i] = fn(items[i]); });
    } else {
      for (auto& item : items) item = fn(item);
    }
  };

  // 1. Coarse grid.
  t0 = Clock::now();
  std::vector<Scored> cands;
  std::vector<uint8_t> even;  // on every other row and column
  const int n = static_cast<int>(std::ceil(radius / grid));
  for (int j = -n; j <= n; ++j)
    for (int i = -n; i <= n; ++i) {
      if (std::hypot(i * grid, j * grid) > radius) continue;
      const GeodeticPoint p = Offset(options.lat_deg, options.lon_deg, i * grid, j * grid);
      if (!window.HeightAt(p.lat_deg, p.lon_deg)) continue;
      Scored s;
      s.lat = p.lat_deg, s.lon = p.lon_deg;
      cands.push_back(s);
      even.push_back(i % 2 == 0 && j % 2 == 0);
    }
  if (cands.empty()) throw InvalidArgument("locate: no DEM data inside the search area");
  {
    // The places on every other row and column first; the others' horizons
    // hinted by the nearest of those (the same horizons, sooner).
    // The pooled posts around the viewpoint are not its ground: left out.
    std::vector<Scored> first, rest;
    for (size_t k = 0; k < cands.size(); ++k) (even[k] ? first : rest).push_back(cands[k]);
    run_all(first, [&](const Scored& s) {
      return score(coarse, s.lat, s.lon, 1.0, options.coarse_max_distance_m, coarse_profiles, 1.0,
                   options.coarse_post_m, nullptr, nullptr, true);
    });
    run_all(rest, [&](const Scored& s) {
      return score(coarse, s.lat, s.lon, 1.0, options.coarse_max_distance_m, coarse_profiles, 1.0,
                   options.coarse_post_m, nullptr, NearestPoints(first, s.lat, s.lon));
    });
    for (size_t k = 0, a = 0, b = 0; k < cands.size(); ++k) cands[k] = even[k] ? first[a++] : rest[b++];
    for (Scored& s : cands) s.points.reset();
  }
  out.coarse_viewpoints = static_cast<int>(cands.size());
  std::sort(cands.begin(), cands.end(), [](const Scored& a, const Scored& b) { return a.cost < b.cost; });
  std::vector<Scored> seeds;  // distinct: at least 3 grid steps apart
  for (const Scored& s : cands) {
    if (!std::isfinite(s.cost)) break;
    bool near = false;
    for (const Scored& t : seeds) near = near || DistanceM(s.lat, s.lon, t.lat, t.lon) < 3.0 * grid;
    if (!near) seeds.push_back(s);
    if (static_cast<int>(seeds.size()) >= options.coarse_keep) break;
  }
  for (Scored& s : seeds) s.coarse_cost = s.cost;
  out.distinctiveness = seeds.size() > 1 ? seeds[1].coarse_cost / std::max(1e-9, seeds[0].coarse_cost) : INFINITY;
  out.coarse_ms = MsSince(t0);
  if (seeds.empty()) {
    out.message = "the skyline is too short or missing: nothing to compare with the DEM horizons";
    return out;
  }

  // 2. Fine: 5 x 5 at half the spacing around each seed, then 3 x 3 at a
  // quarter around the best of those, on the full DEM.
  t0 = Clock::now();
  auto local_grid = [&](const Scored& at, double step, int half) {
    std::vector<Scored> local;
    for (int j = -half; j <= half; ++j)
      for (int i = -half; i <= half; ++i) {
        const GeodeticPoint p = Offset(at.lat, at.lon, i * step, j * step);
        Scored s;
        s.lat = p.lat_deg, s.lon = p.lon_deg;
        local.push_back(s);
      }
    return local;
  };
  auto best_of = [](const std::vector<Scored>& v) {
    return *std::min_element(v.begin(), v.end(), [](const Scored& a, const Scored& b) { return a.cost < b.cost; });
  };
  std::vector<Scored> fine(seeds);
  int tries = std::min<int>(options.register_keep, static_cast<int>(fine.size()));
  for (int k = 0; k < tries; ++k)
    for (const auto& [step, half] : {std::pair{grid / 2, 2}, std::pair{grid / 4, 1}}) {
      const Scored seed = fine[k];
      std::vector<Scored> local = local_grid(seed, step, half);
      // The centre first; the others' horizons hinted by its.
      const size_t centre = local.size() / 2;
      local[centre] = score(window, local[centre].lat, local[centre].lon, 0.25, options.coarse_max_distance_m,
                            fine_profiles, 0.25, 0.5, &seed, nullptr, true);
      const std::vector<Eigen::Vector3d>* hint = local[centre].points.get();
      run_all(local, [&](const Scored& s) {
        if (s.points) return s;  // the centre
        return score(window, s.lat, s.lon, 0.25, options.coarse_max_distance_m, fine_profiles, 0.25, 0.5, &seed, hint);
      });
      local[centre].points.reset();
      out.fine_viewpoints += static_cast<int>(local.size());
      const double cc = fine[k].coarse_cost;
      fine[k] = best_of(local);
      fine[k].coarse_cost = cc;
    }
  std::stable_sort(fine.begin(), fine.begin() + tries,
                   [](const Scored& a, const Scored& b) { return a.cost < b.cost; });
  out.fine_ms = MsSince(t0);

  // 3. Exact: the full registration in a pattern search around each fine
  // place (near ridges carry the position), the least misfit kept; then
  // the answer's Site and its RegisterPhoto.
  t0 = Clock::now();
  for (const Scored& s : fine) {
    LocateCandidate c;
    c.lat_deg = s.lat, c.lon_deg = s.lon, c.cost = s.cost, c.azimuth_deg = s.azimuth, c.hfov_deg = s.hfov;
    c.coarse_cost = s.coarse_cost;
    out.candidates.push_back(c);
  }
  SiteOptions so = options.site;
  so.agl_m = agl;
  so.Check();
  auto registration_options = [&](double sigma_m) {
    PhotoOptions p = po;
    p.position_sigma_m = sigma_m;
    RegistrationOptions ro = PhotoRegistrationOptions(/*altitude_given=*/false, p, image.cols, image.rows);
    ro.narrow_window_restarts = false;  // the places compared alike, one start each (a third of the time)
    ro.bound_search_focal = false;      // and without the projected line search (RegistrationOptions)
    // The lens's distortion is the camera's, not the place's: the places are
    // compared with the pinhole model (and known intrinsics as given), the
    // answer's registration estimates it. A quarter less time per place, the
    // same 13 of 20 dev scenes located, none falsely.
    ro.estimate_distortion = false;
    // Nor the azimuth scan of a plain skyline (RegistrationOptions::
    // scan_plain_skylines): at places whose view holds few pairs of peaks
    // and dips it finds equal fits a few tens of metres apart (cascades_03,
    // located 13 m off without it, was not pinned down with it: 15 of 20
    // dev scenes instead of 16). The answer's registration has it.
    ro.scan_plain_skylines = false;
    return ro;
  };
  struct Polished {
    double lat = 0, lon = 0, misfit = INFINITY;
    bool registered = false;
    bool informative = false;  // enough informative columns to tell the pose there
    std::string message;
    double azimuth = NAN, pitch = NAN;
    HintPoints points;  // its horizon's: hints for its neighbours'
  };
  // Widens c's equal-fit spreads by a place that fits about as well.
  auto widen = [](LocateCandidate& c, double lat, double lon, double azimuth, double pitch) {
    c.position_spread_m = std::max(c.position_spread_m, DistanceM(c.lat_deg, c.lon_deg, lat, lon));
    c.orientation_spread_deg = std::max({c.orientation_spread_deg, std::abs(pitch - c.registered_pitch_deg),
                                         std::abs(std::remainder(azimuth - c.registered_azimuth_deg, 360.0))});
  };
  // Its horizon hinted by `hint` (a neighbour's HorizonPoints).
  auto register_at = [&](double lat, double lon, const RegistrationOptions& ro,
                         const std::vector<Eigen::Vector3d>* hint = nullptr) {
    Polished p;
    p.lat = lat, p.lon = lon;
    const std::optional<double> ground = window.HeightAt(lat, lon);
    if (!ground) return p;
    HorizonOptions ho = so.horizon_options();
    ho.num_threads = 1;
    const GeodeticPoint eye{lat, lon, *ground + agl};
    const HorizonProfile hp = hint ? ComputeHorizonNear(window, eye, ho, *hint) : ComputeHorizon(window, eye, ho);
    p.points = std::make_shared<const std::vector<Eigen::Vector3d>>(HorizonPoints(hp));
    const Registration r = RegisterImage(image, skyline, hp, ro);
    p.misfit = std::isfinite(r.misfit) ? r.misfit : INFINITY;
    p.registered = r.registered;
    p.informative = ro.TellsThePose(r.informative_columns, skyline.width);
    p.message = r.message;
    p.azimuth = r.pose.azimuth_deg, p.pitch = r.pose.pitch_deg;
    return p;
  };
  // Compared at a tight position error (near ridges count): the misfit is
  // least where the near terrain fits too.
  const RegistrationOptions polish_ro = registration_options(kPolishSigmaM);
  std::vector<std::vector<Polished>> seen_of(tries);
  std::vector<Polished> polished(tries);
  // `places` registered (those seen before taken from `seen`), and added to it.
  auto register_places = [&](std::vector<Polished>& places, std::vector<Polished>& seen) {
    std::vector<Polished> todo;
    std::vector<int> from_seen(places.size(), -1);
    for (size_t q = 0; q < places.size(); ++q) {
      for (size_t t = 0; t < seen.size() && from_seen[q] < 0; ++t)
        if (DistanceM(places[q].lat, places[q].lon, seen[t].lat, seen[t].lon) < 0.5) from_seen[q] = static_cast<int>(t);
      if (from_seen[q] < 0) todo.push_back(places[q]);
    }
    // Each horizon hinted by the nearest place seen; when none was, the one
    // nearest the middle of the places first, alone.
    if (!todo.empty() && !NearestPoints(seen, todo[0].lat, todo[0].lon)) {
      double lat = 0, lon = 0;
      for (const Polished& p : todo) lat += p.lat / todo.size(), lon += p.lon / todo.size();
      size_t mid = 0;
      for (size_t q = 1; q < todo.size(); ++q)
        if (DistanceM(lat, lon, todo[q].lat, todo[q].lon) < DistanceM(lat, lon, todo[mid].lat, todo[mid].lon)) mid = q;
      todo[mid] = register_at(todo[mid].lat, todo[mid].lon, polish_ro);
    }
    std::vector<Polished> sources = seen;
    for (const Polished& p : todo)
      if (p.points) sources.push_back(p);
    std::vector<const std::vector<Eigen::Vector3d>*> hint_of(todo.size());
    for (size_t q = 0; q < todo.size(); ++q) hint_of[q] = NearestPoints(sources, todo[q].lat, todo[q].lon);
    std::vector<size_t> order(todo.size());
    for (size_t q = 0; q < todo.size(); ++q) order[q] = q;
    run_all(order, [&](size_t q) {
      if (!todo[q].points) todo[q] = register_at(todo[q].lat, todo[q].lon, polish_ro, hint_of[q]);
      return q;
    });
    for (size_t q = 0, next = 0; q < places.size(); ++q) places[q] = from_seen[q] >= 0 ? seen[from_seen[q]] : todo[next++];
    out.fine_viewpoints += static_cast<int>(todo.size());
    seen.insert(seen.end(), places.begin(), places.end());
  };
  auto better = [](const Polished& p, const Polished& at) {  // registered first, then the least misfit
    return (p.registered && !at.registered) || (p.registered == at.registered && p.misfit < at.misfit);
  };
  // The pattern search from `at`: the 3 x 3 moves while its best is not
  // its centre. Steps of half the spacing (up to 2 moves; the best place
  // only: it also shows how far away an equal fit can be), a quarter (2),
  // an eighth (3), a sixteenth (2), a 32nd (1), from round `first`.
  auto pattern = [&](Polished& at, std::vector<Polished>& seen, int first) {
    constexpr int kStepOf[] = {2, 2, 4, 4, 8, 8, 8, 16, 16, 32};
    Polished moved_from = at;
    for (int round = first; round < 10; ++round) {
      if (round > first && kStepOf[round] == kStepOf[round - 1] && at.lat == moved_from.lat &&
          at.lon == moved_from.lon)
        continue;
      const double step = grid / kStepOf[round];
      moved_from = at;
      std::vector<Polished> local;
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          const GeodeticPoint g = Offset(at.lat, at.lon, k * step, j * step);
          Polished p;
          p.lat = g.lat_deg, p.lon = g.lon_deg;
          local.push_back(p);
        }
      register_places(local, seen);
      for (const Polished& p : local)
        if (better(p, at)) at = p;
    }
  };
  // Candidate i's figures from its polished place and the places seen around it.
  auto settle = [&](int i) {
    LocateCandidate& c = out.candidates[i];
    const Polished& at = polished[i];
    c.lat_deg = at.lat, c.lon_deg = at.lon;
    c.registered_azimuth_deg = at.azimuth, c.registered_pitch_deg = at.pitch;
    // How well the position is pinned: the viewpoints seen that register
    // about as well (misfit within kEqualFit), how far apart they stand and
    // how far apart their orientations are (position and orientation trade
    // off when the terrain is far).
    c.position_spread_m = c.orientation_spread_deg = 0.0;
    double spread2 = 0.0;
    int equal = 0;
    for (const Polished& p : seen_of[i])
      if (at.registered && p.registered && p.misfit <= (1.0 + kEqualFit) * at.misfit) {
        const double d = DistanceM(at.lat, at.lon, p.lat, p.lon);
        spread2 += d * d, ++equal;
        widen(c, p.lat, p.lon, p.azimuth, p.pitch);
      }
    c.position_rms_m = equal ? std::sqrt(spread2 / equal) : 0.0;
    c.tried = true;
    c.registered = at.registered;
    c.misfit = at.misfit;
    c.informative = at.informative;
    c.message = at.message;
  };
  for (int i = 0; i < tries; ++i) {
    LocateCandidate& c = out.candidates[i];
    // Runners-up whose profiles fit clearly worse than the best's are not
    // registered (a distinct skyline); those near it are, to see whether
    // they register as well (then the answer is ambiguous).
    const bool polish = i == 0 || c.cost <= kRunnerUpCostRatio * out.candidates[0].cost;
    Polished& at = polished[i];
    at = Polished{c.lat_deg, c.lon_deg, INFINITY, false, false, "", NAN, NAN, nullptr};
    if (polish)
      pattern(at, seen_of[i], i == 0 ? 0 : 4);
    else
      at = register_at(c.lat_deg, c.lon_deg, polish_ro);  // its misfit only
    settle(i);
  }
  // The pattern stops in the first basin it finds, and the misfit is no
  // smooth bowl: a ring of places a grid step or so around each place that
  // fits nearly as well as the best (within kRingMisfitRatio) is registered
  // too, and the pattern goes on from a ring place that fits better, at
  // most kRingRestarts times per place (rainier_04: polished 255 m from the
  // truth, misfit 0.19, the truth 0.11).
  double least = INFINITY;
  for (int i = 0; i < tries; ++i)
    if (polished[i].registered) least = std::min(least, polished[i].misfit);
  auto ring_probe = [&](int i) {
    for (int restart = 0; restart < kRingRestarts && std::isfinite(least); ++restart) {
      Polished& at = polished[i];
      if (!at.registered || !(at.misfit <= kRingMisfitRatio * least)) break;
      std::vector<Polished> ring;
      for (const double r : {0.75 * grid, 1.25 * grid})
        for (int k = 0; k < kRingDirections; ++k) {
          const double a = 2.0 * kPi * (k + (r > grid ? 0.5 : 0.0)) / kRingDirections;
          const GeodeticPoint g = Offset(at.lat, at.lon, r * std::sin(a), r * std::cos(a));
          Polished p;
          p.lat = g.lat_deg, p.lon = g.lon_deg;
          ring.push_back(p);
        }
      register_places(ring, seen_of[i]);
      const Polished* best_ring = nullptr;
      for (const Polished& p : ring)
        if (p.registered && p.misfit < (1.0 - kRingMinGain) * at.misfit && (!best_ring || p.misfit < best_ring->misfit))
          best_ring = &p;
      if (!best_ring) break;
      at = *best_ring;
      pattern(at, seen_of[i], 2);
      settle(i);
      least = std::min(least, at.misfit);
    }
  };
  for (int i = 0; i < tries; ++i) ring_probe(i);
  // The registered place of least misfit (-1: none).
  auto least_misfit = [&] {
    int best = -1;
    for (int i = 0; i < tries; ++i)
      if (out.candidates[i].registered && (best < 0 || out.candidates[i].misfit < out.candidates[best].misfit))
        best = i;
    return best;
  };
  // The answer (`best`, or the first place when none registered) registered
  // at the last 3 x 3's half spacing.
  const double answer_sigma_m = std::max(kAnswerSigmaFloorM, grid / 64);
  po.position_sigma_m = answer_sigma_m;
  int answer = 0;
  auto register_answer = [&](int best) {
    answer = best >= 0 ? best : 0;
    // Other places that register about as well count as equal fits too (two
    // polished places 400 m apart that fit alike leave the position open by
    // that much, and the orientation by what separates theirs).
    if (best >= 0)
      for (int i = 0; i < tries; ++i) {
        LocateCandidate &b = out.candidates[best], &c = out.candidates[i];
        if (i != best && c.registered && c.misfit <= (1.0 + kEqualFit) * b.misfit)
          widen(b, c.lat_deg, c.lon_deg, c.registered_azimuth_deg, c.registered_pitch_deg);
      }
    out.site = std::make_unique<Site>(TerrainWindow(window), out.candidates[answer].lat_deg,
                                      out.candidates[answer].lon_deg, so, pool);
    out.registration = RegisterPhoto(*out.site, image, po, pool);
  };
  int best = least_misfit();
  register_answer(best);
  // A best place whose registration there cannot tell the pose (its near
  // horizon fitted only at the polish's tight position error: alps_03's best
  // place 3.8 km off, 11% of the columns informative) is neither the answer
  // nor a rival; the next registered place is registered instead, once.
  if (const Registration& r = out.registration.registration;
      best >= 0 && !r.registered &&
      !registration_options(answer_sigma_m).TellsThePose(r.informative_columns, skyline.width)) {
    LocateCandidate& dropped = out.candidates[best];
    dropped.registered = dropped.informative = false;
    dropped.message = r.message;
    best = least_misfit();
    if (best >= 0) register_answer(best);
  }
  // An answer its position check refused (its rings 1-3 km around fit
  // clearly better by the check's search cost): that place is polished as
  // a candidate (pattern and ring), and locate's own measure decides. When
  // it fits better there too, it is the answer (registered in turn, twice
  // at most); when it fits clearly worse (misfit 15% over the answer's or
  // not registered), the answer is registered without the check, whose
  // rings the search has covered, and that place stays a rival for the
  // distinctiveness test below (rainier_00: from the truth the check's ring
  // fits 10% better 1 km east, cost ratio 0.907; from 77 m off, 0.81);
  // in between, the refusal stands.
  for (int follow = 0; follow < kFollowChecks && best >= 0; ++follow) {
    const PhotoRegistration& reg = out.registration;
    if (reg.registration.registered || !reg.position_check || reg.position_check->consistent) break;
    const LocateCandidate refused = out.candidates[answer];
    const GeodeticPoint to = Offset(refused.lat_deg, refused.lon_deg, reg.position_check->best_offset_en_m.x(),
                                    reg.position_check->best_offset_en_m.y());
    if (!window.HeightAt(to.lat_deg, to.lon_deg)) break;
    LocateCandidate c;
    c.lat_deg = to.lat_deg, c.lon_deg = to.lon_deg, c.cost = refused.cost, c.coarse_cost = refused.coarse_cost;
    c.azimuth_deg = refused.registered_azimuth_deg, c.hfov_deg = refused.hfov_deg;
    out.candidates.insert(out.candidates.begin() + tries, c);
    polished.push_back(Polished{to.lat_deg, to.lon_deg, INFINITY, false, false, "", NAN, NAN, nullptr});
    seen_of.emplace_back();
    const int k = tries++;
    pattern(polished[k], seen_of[k], 0);
    settle(k);
    ring_probe(k);
    const LocateCandidate& there = out.candidates[k];
    std::ostringstream note;
    note.precision(3);
    note << "the position check's better place (" << std::lround(reg.position_check->OffsetM()) << " m at "
         << std::lround(reg.position_check->BearingDeg()) << " deg, cost ratio " << reg.position_check->cost_ratio
         << ") polished to " << std::lround(DistanceM(refused.lat_deg, refused.lon_deg, there.lat_deg, there.lon_deg))
         << " m from the answer";
    if (there.registered && there.misfit < refused.misfit) {
      out.candidates[answer].registered = false;
      out.candidates[answer].message = reg.registration.message;
      note << ", misfit " << there.misfit << " against the answer's " << refused.misfit << ": registered there";
      out.followed_checks.push_back(note.str());
      best = least_misfit();
      register_answer(best);
      continue;
    }
    if (!there.registered || there.misfit >= (1.0 + kEqualFit) * refused.misfit) {
      if (there.registered)
        note << ", misfit " << there.misfit;
      else
        note << ", not registered";
      note << " against the answer's " << refused.misfit << ": the answer registered without the check";
      out.followed_checks.push_back(note.str());
      PhotoOptions unchecked = po;
      unchecked.check_position.reset();
      out.registration = RegisterPhoto(*out.site, image, unchecked, pool);
    }
    break;
  }
  out.register_ms = MsSince(t0);
  std::swap(out.candidates[0], out.candidates[answer]);
  if (best < 0) {
    out.message = "no candidate viewpoint registers: the skyline is not distinctive enough in the area";
    return out;
  }
  if (!out.registration.registration.registered) {  // its second look, rival search or position check refused it
    out.message = "the best place does not register: " + out.registration.registration.message;
    return out;
  }
  if (const LocateCandidate& a = out.candidates[0]; a.orientation_spread_deg > options.max_orientation_spread_deg) {
    std::ostringstream why;
    why.precision(3);
    why << "the position is not pinned down: viewpoints up to " << std::lround(a.position_spread_m)
        << " m apart fit almost equally well, with orientations up to " << a.orientation_spread_deg << " deg apart";
    out.message = why.str();
    return out;
  }

  // A searched position has had thousands of chances to fit by accident:
  // the answer must fit closely as well (misfit per column).
  if (!(out.candidates[0].misfit <= options.max_misfit)) {
    std::ostringstream why;
    why.precision(3);
    why << "the best place fits too loosely for a searched position (misfit " << out.candidates[0].misfit << ", at most "
        << options.max_misfit << ")";
    out.message = why.str();
    return out;
  }
  // ... and carry more evidence than a given position needs.
  if (const double nats = out.registration.registration.evidence_nats; !(nats >= options.min_evidence_nats)) {
    std::ostringstream why;
    why.precision(3);
    why << "the skyline carries too little evidence for a searched position (" << nats << " nats, at least "
        << options.min_evidence_nats << "): a plain skyline fits places far apart";
    out.message = why.str();
    return out;
  }
  // The other places' registrations must fit clearly worse (registered or
  // not: a place whose skyline nearly fits the photo is a rival), those
  // that can tell the pose at all: where the horizon is too near for the
  // DEM (fewer informative columns than a registration needs), the DEM
  // error model's wide tolerance lets a loose fit look close (alps_03: a
  // place 2.3 km away, 19% of the columns informative, misfit 0.86 against
  // the answer's 0.91 at 31 m from the truth).
  out.registration_distinctiveness = INFINITY;
  for (int i = 1; i < tries; ++i) {
    const LocateCandidate &b = out.candidates[0], &c = out.candidates[i];
    if (c.tried && c.informative && std::isfinite(c.misfit) &&
        DistanceM(b.lat_deg, b.lon_deg, c.lat_deg, c.lon_deg) > 3.0 * grid)
      out.registration_distinctiveness = std::min(out.registration_distinctiveness, c.misfit / b.misfit);
  }
  if (out.registration_distinctiveness < options.min_distinctiveness) {
    std::ostringstream why;
    why.precision(3);
    why << "ambiguous: another place in the area registers almost as well (misfit ratio "
        << out.registration_distinctiveness << ", " << options.min_distinctiveness << " needed)";
    out.message = why.str();
    return out;
  }
  out.located = true;
  out.message = "located";
  return out;
}

}  // namespace horizonreg
