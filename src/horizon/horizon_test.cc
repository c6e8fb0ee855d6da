// SPDX-License-Identifier: MIT
#include "horizon/horizon.h"

#include <gtest/gtest.h>

#include <GeographicLib/LocalCartesian.hpp>
#include <algorithm>
#include <numeric>
#include <thread>

#include "horizon/sweep.h"
#include "testing/shared_data.h"
#include "testing/synthetic_dem.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

using testing::ConeHeight;
using testing::SynthesizeDem;
using testing::WindowOf;

TEST(HorizonOptions, DefaultsAreValid) {
  HorizonOptions o;
  EXPECT_NO_THROW(o.Check());
  EXPECT_EQ(o.NumBins(), 1440);
  EXPECT_NO_THROW(RidgeOptions{}.Check());
}

TEST(HorizonOptions, RejectsBadValuesNamingTheField) {
  HorizonOptions o;
  o.azimuth_step_deg = 0.7;
  try {
    o.Check();
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("azimuth_step_deg"), std::string::npos);
  }
  o.azimuth_step_deg = NAN;
  EXPECT_THROW(o.Check(), InvalidArgument);
  o = {};
  o.max_distance_m = -1;
  EXPECT_THROW(o.Check(), InvalidArgument);
  o = {};
  o.refraction = NAN;
  EXPECT_THROW(o.Check(), InvalidArgument);
}

TEST(FastAtan2, IsAccurateEverywhere) {
  double worst = 0;
  for (double a = -kPi; a <= kPi; a += 1e-4) {
    for (double r : {1e-3, 1.0, 1e5}) {
      const double y = r * std::sin(a), x = r * std::cos(a);
      worst = std::max(worst, std::abs(AngDiffDeg(RadToDeg(FastAtan2(y, x)), RadToDeg(std::atan2(y, x)))));
    }
  }
  EXPECT_LT(worst, RadToDeg(2e-7));
}

// Elevation angle of a point from an observer, independently through
// GeographicLib, with refraction k.
double ElevationDeg(const GeodeticPoint& obs, const GeodeticPoint& p, double k) {
  GeographicLib::LocalCartesian lc(obs.lat_deg, obs.lon_deg, obs.height_m);
  double x, y, z;
  lc.Forward(p.lat_deg, p.lon_deg, p.height_m, x, y, z);
  const double d = std::hypot(x, y);
  return RadToDeg(std::atan2(z + k * d * d / (2 * 6371000.0), d));
}

TEST(ComputeHorizon, SingleConePeakAppearsAtItsAzimuth) {
  // A 2000 m cone 30 km north-east of the observer on a flat plane.
  const double lat0 = 45.0, lon0 = 7.0;
  const double peak_lat = 45.19, peak_lon = 7.27;
  DemGrid g = SynthesizeDem(45.5, 6.6, 0.002, 501, 401, ConeHeight(peak_lat, peak_lon, 300.0, 2000.0, 6000.0));
  // Put a post exactly on the summit: shift the grid so it has one there.
  g.lat0_deg = peak_lat + 155 * 0.002;
  g.lon0_deg = peak_lon - 335 * 0.002;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c)
      g.height_m[r * g.width + c] =
          static_cast<float>(ConeHeight(peak_lat, peak_lon, 300.0, 2000.0, 6000.0)(g.LatAt(c, r), g.LonAt(c, r)));
  TerrainWindow w = WindowOf(std::move(g));
  for (double k : {0.0, 0.13}) {
    HorizonOptions o;
    o.refraction = k;
    const GeodeticPoint obs = ResolveObserver(w, lat0, lon0, 1.7, std::nullopt);
    HorizonProfile p = ComputeHorizon(w, obs, o);
    ASSERT_EQ(p.size(), 1440);
    const int top = static_cast<int>(
        std::max_element(p.elevation_deg.begin(), p.elevation_deg.end(), [](double a, double b) { return !(a >= b); }) -
        p.elevation_deg.begin());
    GeographicLib::LocalCartesian lc(lat0, lon0, 0);
    double x, y, z;
    lc.Forward(peak_lat, peak_lon, 0, x, y, z);
    const double peak_az = WrapAzimuthDeg(RadToDeg(std::atan2(x, y)));
    EXPECT_LE(std::abs(AngDiffDeg(p.AzimuthDeg(top), peak_az)), 0.125 + 1e-9);
    EXPECT_NEAR(p.elevation_deg[top], ElevationDeg(obs, {peak_lat, peak_lon, 2300.0}, k), 1e-6);
    double xs, ys, zs;  // the summit itself, 2300 m up: its horizontal ENU distance
    lc.Forward(peak_lat, peak_lon, 2300.0, xs, ys, zs);
    EXPECT_NEAR(p.distance_m[top], std::hypot(xs, ys), 0.01);
    EXPECT_NEAR(p.lat_deg[top], peak_lat, 1e-7);
    EXPECT_NEAR(p.lon_deg[top], peak_lon, 1e-7);
    EXPECT_NEAR(p.height_m[top], 2300.0, 1e-3);
    // The cone's flanks fall 1 m in 3 from the summit; the plain around it
    // is flat (the relief slope sets how much the grid cuts off a peak).
    ASSERT_EQ(p.relief_slope.size(), p.elevation_deg.size());
    EXPECT_NEAR(p.relief_slope[top], 2000.0 / 6000.0, 0.1);
    std::vector<double> slopes;
    for (double v : p.relief_slope)
      if (std::isfinite(v)) slopes.push_back(v);
    ASSERT_GT(slopes.size(), 1000u);
    std::nth_element(slopes.begin(), slopes.begin() + slopes.size() / 2, slopes.end());
    EXPECT_LT(slopes[slopes.size() / 2], 0.01);
  }
}

TEST(ComputeHorizon, FlatEarthGivesTheGeometricDipAndHorizonDistance) {
  // Sea-level plane, eye 100 m up: the horizon dips by sqrt(2 h (1 - k) / R)
  // at distance sqrt(2 h R / (1 - k)).
  DemGrid g = SynthesizeDem(45.6, 6.2, 0.004, 401, 301, [](double, double) { return 0.0; });
  TerrainWindow w = WindowOf(std::move(g));
  for (double k : {0.0, 0.13}) {
    HorizonOptions o;
    o.refraction = k;
    const HorizonProfile p = ComputeHorizon(w, {45.0, 7.0, 100.0}, o);
    const double r_earth = 6367000.0;  // mean radius of curvature at 45 deg
    const double dip = -RadToDeg(std::sqrt(2 * 100.0 * (1 - k) / r_earth));
    for (int i = 0; i < p.size(); i += 60) {
      EXPECT_NEAR(p.elevation_deg[i], dip, 0.003) << "azimuth " << p.AzimuthDeg(i);
      EXPECT_NEAR(p.distance_m[i], std::sqrt(2 * 100.0 * r_earth / (1 - k)), 3000.0);
    }
  }
}

TEST(ComputeHorizon, NoSegmentIsEmptyNearTheObserverOnASlope) {
  // Observer in the middle of a 5-post wide tilted plane (slope 10% to the
  // east): near cells span many segments and must fill all of them.
  DemGrid g =
      SynthesizeDem(45.002, 6.998, 0.001, 5, 5, [](double, double lon) { return 100.0 + (lon - 7.0) * 7863.0; });
  TerrainWindow w = WindowOf(std::move(g));
  const GeodeticPoint obs = ResolveObserver(w, 45.0003, 7.0004, 1.7, std::nullopt);
  const HorizonProfile p = ComputeHorizon(w, obs, HorizonOptions{});
  for (int i = 0; i < p.size(); ++i) ASSERT_TRUE(std::isfinite(p.elevation_deg[i])) << "bin " << i;
  EXPECT_GT(p.ElevationAtDeg(90.0), p.ElevationAtDeg(270.0));
  EXPECT_GT(p.ElevationAtDeg(90.0), 2.0);
  EXPECT_LT(p.ElevationAtDeg(270.0), -4.0);
}

TEST(ComputeHorizon, ThreadCountDoesNotChangeTheResult) {
  DemGrid g = SynthesizeDem(45.3, 6.7, 0.002, 301, 301, ConeHeight(45.1, 7.1, 200.0, 1500.0, 9000.0));
  TerrainWindow w = WindowOf(std::move(g));
  HorizonOptions one, three;
  one.num_threads = 1;
  three.num_threads = 3;
  const HorizonProfile a = ComputeHorizon(w, {45.0, 7.0, 210.0}, one);
  const HorizonProfile b = ComputeHorizon(w, {45.0, 7.0, 210.0}, three);
  for (int i = 0; i < a.size(); ++i) EXPECT_EQ(a.elevation_deg[i], b.elevation_deg[i]);
  // On a shared pool, also from inside another parallel loop (a batch of
  // photos): the same horizon, distances and positions included.
  ThreadPool pool(2);
  HorizonOptions shared;
  shared.pool = &pool;
  std::vector<HorizonProfile> nested(3);
  pool.ParallelFor(nested.size(), [&](size_t k, int) { nested[k] = ComputeHorizon(w, {45.0, 7.0, 210.0}, shared); });
  for (const HorizonProfile& c : nested)
    for (int i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a.elevation_deg[i], c.elevation_deg[i]);
      if (std::isfinite(a.distance_m[i])) {
        EXPECT_EQ(a.distance_m[i], c.distance_m[i]);
        EXPECT_EQ(a.lat_deg[i], c.lat_deg[i]);
      }
    }
}

TEST(ComputeHorizon, SectorGivesTheSameBinsInsideAndNaNOutside) {
  DemGrid g = SynthesizeDem(45.3, 6.7, 0.002, 301, 301, ConeHeight(45.1, 7.1, 200.0, 1500.0, 9000.0));
  TerrainWindow w = WindowOf(std::move(g));
  HorizonOptions full;
  full.num_threads = 1;
  const HorizonProfile a = ComputeHorizon(w, {45.0, 7.0, 210.0}, full);
  // Around the cone (north-east), and a sector across north.
  for (const auto& [center, half] : {std::pair{35.0, 25.0}, std::pair{350.0, 30.0}}) {
    HorizonOptions sector = full;
    sector.sector_center_deg = center;
    sector.sector_half_width_deg = half;
    const HorizonProfile b = ComputeHorizon(w, {45.0, 7.0, 210.0}, sector);
    ASSERT_EQ(a.size(), b.size());
    int inside = 0;
    for (int i = 0; i < a.size(); ++i) {
      if (std::abs(std::remainder(a.AzimuthDeg(i) - center, 360.0)) <= half) {
        EXPECT_TRUE(sector.InSector(a.AzimuthDeg(i)));
        ++inside;
        EXPECT_EQ(a.elevation_deg[i], b.elevation_deg[i]) << "bin " << i;
        if (std::isfinite(a.distance_m[i])) {
          EXPECT_EQ(a.distance_m[i], b.distance_m[i]) << "bin " << i;
        }
      } else {
        EXPECT_TRUE(std::isnan(b.elevation_deg[i])) << "bin " << i;
      }
    }
    EXPECT_NEAR(inside, 2 * half / a.azimuth_step_deg + 1, 1);
  }
  HorizonOptions bad;
  bad.sector_half_width_deg = 0.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
  bad.sector_half_width_deg = 181.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
}

// Hints from a horizon computed nearby (HorizonHints) cull terrain sooner
// but must not change the result, even when a hint is too high (the sweep
// is run again without hints then).
TEST(ComputeHorizon, HintsLeaveTheResultAsItIs) {
  const auto cone = ConeHeight(45.1, 7.1, 200.0, 1500.0, 9000.0);
  DemGrid g = SynthesizeDem(45.3, 6.7, 0.002, 301, 301, [&](double lat, double lon) {
    return cone(lat, lon) + 60.0 * std::sin(lat * 900.0) * std::cos(lon * 700.0);  // ridges and valleys
  });
  TerrainWindow w = WindowOf(std::move(g));
  const GeodeticPoint a{45.0, 7.0, 400.0}, b{45.002, 7.003, 420.0};  // about 360 m apart
  auto expect_same = [](const HorizonProfile& x, const HorizonProfile& y) {
    ASSERT_EQ(x.size(), y.size());
    for (int i = 0; i < x.size(); ++i) {
      ASSERT_EQ(std::isfinite(x.elevation_deg[i]), std::isfinite(y.elevation_deg[i])) << "bin " << i;
      if (!std::isfinite(x.elevation_deg[i])) continue;
      EXPECT_EQ(x.elevation_deg[i], y.elevation_deg[i]) << "bin " << i;
      EXPECT_EQ(x.distance_m[i], y.distance_m[i]) << "bin " << i;
      EXPECT_EQ(x.lat_deg[i], y.lat_deg[i]) << "bin " << i;
    }
  };
  for (const double half : {180.0, 30.0}) {
    HorizonOptions o;
    o.num_threads = 2;
    o.sector_center_deg = 40.0;
    o.sector_half_width_deg = half;
    const HorizonProfile at_a = ComputeHorizon(w, a, o), at_b = ComputeHorizon(w, b, o);
    // Most of b's bins are hinted, each below its horizon.
    const std::vector<double> hints = HorizonHints(HorizonPoints(at_a), b, o);
    int hinted = 0, inside = 0;
    for (int i = 0; i < at_b.size(); ++i) {
      if (!std::isfinite(at_b.elevation_deg[i])) continue;
      ++inside;
      if (!std::isfinite(hints[i])) continue;
      ++hinted;
      EXPECT_LT(hints[i], std::tan(DegToRad(at_b.elevation_deg[i]))) << "bin " << i;
    }
    EXPECT_GT(hinted, 0.6 * inside);
    expect_same(at_b, ComputeHorizonNear(w, b, o, at_a));
    // Hints above the terrain in some bins: the same horizon all the same.
    std::vector<double> high = hints;
    for (int i = 0; i < at_b.size(); i += 7)
      if (std::isfinite(at_b.elevation_deg[i])) high[i] = std::tan(DegToRad(at_b.elevation_deg[i])) + 0.01;
    HorizonOptions hinted_high = o;
    hinted_high.hint_tan_el = &high;
    expect_same(at_b, ComputeHorizon(w, b, hinted_high));
  }
  HorizonOptions bad;
  const std::vector<double> short_hints(10, 0.0);
  bad.hint_tan_el = &short_hints;
  EXPECT_THROW(bad.Check(), InvalidArgument);
}

// A projected grid's posts carry their own sines and cosines
// (DemGrid::post_trig, from IndexTrig): the sweep forms those of each
// post's longitude difference from the observer by the difference
// formulae. The horizon must be the one computed from the posts' degrees.
TEST(ComputeHorizon, APostsCachedTrigonometryGivesTheSameHorizon) {
  DemGrid g = SynthesizeDem(45.3, 6.7, 0.002, 301, 301, ConeHeight(45.1, 7.1, 200.0, 1500.0, 9000.0));
  g.separable = false;
  g.lat_deg.resize(g.height_m.size()), g.lon_deg.resize(g.height_m.size());
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      // A slight shear, as a projected grid has: not separable.
      const size_t k = static_cast<size_t>(r) * g.width + c;
      g.lat_deg[k] = g.lat0_deg + r * g.dlat_deg + 1e-6 * c;
      g.lon_deg[k] = g.lon0_deg + c * g.dlon_deg - 2e-6 * r;
    }
  g.IndexPositions();
  g.IndexTrig();
  ASSERT_EQ(g.post_trig.size(), 4 * g.height_m.size());
  DemGrid plain = g;
  plain.post_trig.clear();
  const TerrainWindow cached = WindowOf(std::move(g)), uncached = WindowOf(std::move(plain));
  HorizonOptions o;
  o.num_threads = 1;
  for (const GeodeticPoint& eye : {GeodeticPoint{45.0, 7.0, 210.0}, GeodeticPoint{45.12, 7.05, 900.0}}) {
    const HorizonProfile a = ComputeHorizon(cached, eye, o), b = ComputeHorizon(uncached, eye, o);
    ASSERT_EQ(a.size(), b.size());
    int finite = 0;
    for (int i = 0; i < a.size(); ++i) {
      ASSERT_EQ(std::isfinite(a.elevation_deg[i]), std::isfinite(b.elevation_deg[i])) << "bin " << i;
      if (!std::isfinite(a.elevation_deg[i])) continue;
      ++finite;
      EXPECT_NEAR(a.elevation_deg[i], b.elevation_deg[i], 1e-9) << "bin " << i;
      // The distance to within 0.5 m: where the horizon's point is one of a
      // nearly level run, rounding at 1e-16 may pick a neighbouring one.
      if (std::isfinite(a.distance_m[i])) {
        EXPECT_NEAR(a.distance_m[i], b.distance_m[i], 0.5) << "bin " << i;
      }
    }
    EXPECT_GT(finite, a.size() / 2);
  }
}

TEST(ComputeRidges, FindsANearRidgeInFrontOfAHigherFarOne) {
  // Looking north: a 400 m ridge at 5 km, a 4500 m massif at 40 km.
  auto near_ridge = ConeHeight(45.045, 7.0, 0.0, 400.0, 1500.0);
  auto far_massif = ConeHeight(45.36, 7.0, 0.0, 4500.0, 8000.0);
  DemGrid g = SynthesizeDem(45.5, 6.8, 0.001, 401, 521,
                            [&](double la, double lo) { return std::max(near_ridge(la, lo), far_massif(la, lo)); });
  TerrainWindow w = WindowOf(std::move(g));
  const GeodeticPoint obs{45.0, 7.0, 1.7};
  const HorizonProfile p = ComputeHorizon(w, obs, HorizonOptions{});
  const auto ridges = ComputeRidges(w, obs, HorizonOptions{}, RidgeOptions{});
  ASSERT_EQ(ridges.size(), 1440u);
  ASSERT_FALSE(ridges[0].empty());
  const double ridge_el = ElevationDeg(obs, {45.045, 7.0, 400.0}, 0.13);
  EXPECT_NEAR(ridges[0][0].elevation_deg, ridge_el, 0.05);
  EXPECT_NEAR(ridges[0][0].distance_m, 5000.0, 200.0);
  EXPECT_GT(p.elevation_deg[0], ridges[0][0].elevation_deg + 1.0);  // the massif above it
  EXPECT_TRUE(ridges[720].empty());                                 // looking south over the flat plain
}

// ---- Independent reference: fine ray march over the same bilinear surface ----
//
// Everything here goes through GeographicLib and DemGrid::HeightAt (the
// surface's definition), not through the sweep. A sector's maximum is the
// larger of
//  - the posts whose exact azimuth lies in the sector, and
//  - `subrays` rays spread evenly over the sector (both edges included),
//    each marched with a step of 1% of the distance (0.5 m to spacing / 3)
//    in the observer's tangent plane, mapped to lat/lon by GeographicLib,
//    every local maximum near the ray's best refined by golden-section
//    search (the bilinear surface has creases on grid lines).
// Terrain counts when the four posts of its cell lie within max_d, as in
// ComputeHorizon.
class ReferenceHorizon {
 public:
  ReferenceHorizon(const TerrainWindow& w, const GeodeticPoint& obs, double max_d, double k)
      : w_(w), obs_(obs), max_d_(max_d), k_(k) {
    GeographicLib::LocalCartesian lc(obs.lat_deg, obs.lon_deg, obs.height_m);
    for (const DemGrid& g : w.grids) {
      std::vector<Post> posts(g.height_m.size());
      for (int r = 0; r < g.height; ++r)
        for (int c = 0; c < g.width; ++c) {
          Post& p = posts[static_cast<size_t>(r) * g.width + c];
          const double h = g.At(c, r);
          if (!std::isfinite(h)) continue;
          double x, y, u;
          lc.Forward(g.LatAt(c, r), g.LonAt(c, r), h, x, y, u);
          p.d = std::hypot(x, y);
          p.az = WrapAzimuthDeg(RadToDeg(std::atan2(x, y)));
          p.tan_el = (u + k * p.d * p.d / (2 * 6371000.0)) / p.d;
        }
      posts_.push_back(std::move(posts));
      spacing_ = std::min(spacing_, g.SpacingM());
    }
  }

  std::vector<double> Compute(double step_deg, int subrays) const {
    const int n = static_cast<int>(std::lround(360.0 / step_deg));
    std::vector<double> best(n, -INFINITY);
    for (const auto& posts : posts_)
      for (const Post& p : posts) {
        if (!(p.d > 0.5 && p.d <= max_d_)) continue;
        const int i = static_cast<int>(std::floor(p.az / step_deg + 0.5)) % n;
        best[i] = std::max(best[i], p.tan_el);
      }
    std::vector<std::thread> pool;
    for (int t = 0; t < 2; ++t)
      pool.emplace_back([&, t] {
        GeographicLib::LocalCartesian lc(obs_.lat_deg, obs_.lon_deg, obs_.height_m);
        for (int i = t; i < n; i += 2)
          for (int s = 0; s < subrays; ++s)
            best[i] = std::max(best[i], MarchRay(lc, i * step_deg + step_deg * (-0.5 + s / double(subrays - 1))));
      });
    for (auto& th : pool) th.join();
    std::vector<double> out(n, NAN);
    for (int i = 0; i < n; ++i)
      if (std::isfinite(best[i])) out[i] = RadToDeg(std::atan(best[i]));
    return out;
  }

 private:
  struct Post {
    double d = -1, az = 0, tan_el = -INFINITY;
  };

  // tan(elevation) of the surface at distance d along azimuth az_deg, or -inf.
  double Sample(const GeographicLib::LocalCartesian& lc, double az_rad, double d) const {
    double lat, lon, h;
    lc.Reverse(d * std::sin(az_rad), d * std::cos(az_rad), 0.0, lat, lon, h);
    for (size_t gi = 0; gi < w_.grids.size(); ++gi) {
      const DemGrid& g = w_.grids[gi];
      const auto px = g.PixelOf(lat, lon);
      if (!px) continue;
      const auto z = g.HeightAt(lat, lon);
      if (!z) continue;
      const int c = std::min(static_cast<int>(px->first), g.width - 2),
                r = std::min(static_cast<int>(px->second), g.height - 2);
      const auto& posts = posts_[gi];
      for (int dr = 0; dr < 2; ++dr)
        for (int dc = 0; dc < 2; ++dc)
          if (!(posts[static_cast<size_t>(r + dr) * g.width + c + dc].d <= max_d_)) return -INFINITY;
      double x, y, u;
      lc.Forward(lat, lon, *z, x, y, u);
      const double dd = std::hypot(x, y);
      return (u + k_ * dd * dd / (2 * 6371000.0)) / dd;
    }
    return -INFINITY;
  }

  double MarchRay(const GeographicLib::LocalCartesian& lc, double az_deg) const {
    const double az = DegToRad(az_deg);
    std::vector<std::pair<double, double>> samples;  // (d, tan_el)
    for (double d = 1.0; d <= max_d_ + 2 * spacing_; d += std::clamp(0.01 * d, 0.5, spacing_ / 3)) {
      samples.emplace_back(d, Sample(lc, az, d));
    }
    double best = -INFINITY;
    for (const auto& s : samples) best = std::max(best, s.second);
    const double margin = 0.006;  // > the worst miss of a crease between samples
    for (size_t i = 1; i + 1 < samples.size(); ++i) {
      if (!(samples[i].second >= samples[i - 1].second && samples[i].second >= samples[i + 1].second)) continue;
      if (samples[i].second < best - margin) continue;
      double lo = samples[i - 1].first, hi = samples[i + 1].first;
      const double g = 0.6180339887498949;
      double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
      double f1 = Sample(lc, az, x1), f2 = Sample(lc, az, x2);
      for (int it = 0; it < 30; ++it) {
        if (f1 < f2) {
          lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = Sample(lc, az, x2);
        } else {
          hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = Sample(lc, az, x1);
        }
      }
      best = std::max({best, f1, f2});
    }
    return best;
  }

  const TerrainWindow& w_;
  GeodeticPoint obs_;
  double max_d_, k_;
  double spacing_ = INFINITY;
  std::vector<std::vector<Post>> posts_;
};

struct Viewpoint {
  const char* name;
  std::vector<const char*> files;
  double lat, lon;
};

void CompareWithReference(const Viewpoint& v, const std::filesystem::path& shared) {
  std::vector<std::string> files;
  for (const char* f : v.files) files.push_back((shared / "dem" / f).string());
  Terrain terrain(files);
  HorizonOptions o;
  o.max_distance_m = 25'000.0;
  const TerrainWindow w = terrain.ReadWindow({v.lat, v.lon, 0.0}, o.max_distance_m);
  const GeodeticPoint obs = ResolveObserver(w, v.lat, v.lon, 1.7, std::nullopt);
  const HorizonProfile p = ComputeHorizon(w, obs, o);
  const auto ref = ReferenceHorizon(w, obs, o.max_distance_m, o.refraction).Compute(o.azimuth_step_deg, 5);
  std::vector<double> diff;
  if (std::getenv("HR_DEBUG_REF")) {
    for (int i = 0; i < p.size(); ++i)
      if (std::abs(p.elevation_deg[i] - ref[i]) > 0.03)
        std::printf("  bin %d az %.2f ours %.4f ref %.4f dist %.0f\n", i, p.AzimuthDeg(i), p.elevation_deg[i], ref[i],
                    p.distance_m[i]);
  }
  for (int i = 0; i < p.size(); ++i) {
    ASSERT_TRUE(std::isfinite(p.elevation_deg[i])) << v.name << " bin " << i;
    ASSERT_TRUE(std::isfinite(ref[i])) << v.name << " bin " << i;
    diff.push_back(std::abs(p.elevation_deg[i] - ref[i]));
  }
  std::sort(diff.begin(), diff.end());
  const double median = diff[diff.size() / 2], p95 = diff[diff.size() * 95 / 100], worst = diff.back();
  std::printf("[ reference ] %-28s median |diff| %.5f deg, p95 %.5f deg, max %.4f deg (%zu bins)\n", v.name, median,
              p95, worst, diff.size());
  EXPECT_LE(median, 0.01) << v.name;
  EXPECT_LE(p95, 0.05) << v.name;
}

// An edge of near terrain spans many bins; one that lies under every bin
// it crosses is skipped (HorizonAccumulator::EdgeBelowItsSectors), bounded
// by its higher end over its nearest point to the observer. An observer
// 250 m from a crest running north-south, with rolling hills about: near
// edges, each across tens of bins, set nearly every bin. The horizon must
// not depend on when the edges are read: on one thread or three, and with
// every bin raised beforehand to just under its horizon (hints), when
// almost every edge is skipped and one skipped wrongly would leave its
// bins lower. The near bins agree with a fine ray march.
TEST(ComputeHorizon, NearEdgesUnderTheirBinsAreSkippedWithoutChangingTheHorizon) {
  DemGrid g = SynthesizeDem(45.2, 6.9, 0.0015, 201, 201, [&](double lat, double lon) {
    const double east_m = (lon - 7.0032) * 78'700.0;  // the crest, about 250 m east of the observer
    return 300.0 + 25.0 * std::sin(lat * 1700.0) * std::cos(lon * 1300.0) +
           90.0 * std::exp(-east_m * east_m / (2.0 * 60.0 * 60.0));
  });
  TerrainWindow w = WindowOf(std::move(g));
  const GeodeticPoint obs = ResolveObserver(w, 45.0004, 7.0002, 2.0, std::nullopt);
  HorizonOptions one, three;
  one.num_threads = 1;
  one.max_distance_m = three.max_distance_m = 20'000.0;
  three.num_threads = 3;
  const HorizonProfile a = ComputeHorizon(w, obs, one), b = ComputeHorizon(w, obs, three);
  std::vector<double> under(a.size());
  for (int i = 0; i < a.size(); ++i) under[i] = std::tan(DegToRad(a.elevation_deg[i])) - 0.002;
  HorizonOptions hinted = one;
  hinted.hint_tan_el = &under;
  const HorizonProfile c = ComputeHorizon(w, obs, hinted);
  int near = 0;
  for (int i = 0; i < a.size(); ++i) {
    ASSERT_TRUE(std::isfinite(a.elevation_deg[i])) << "bin " << i;
    for (const HorizonProfile* x : {&b, &c}) {
      EXPECT_EQ(a.elevation_deg[i], x->elevation_deg[i]) << "bin " << i;
      EXPECT_EQ(a.distance_m[i], x->distance_m[i]) << "bin " << i;
    }
    near += a.distance_m[i] < 600.0;
  }
  EXPECT_GT(near, 1000);
  const auto ref = ReferenceHorizon(w, obs, one.max_distance_m, one.refraction).Compute(one.azimuth_step_deg, 5);
  std::vector<double> diff;
  for (int i = 0; i < a.size(); ++i)
    if (a.distance_m[i] < 600.0) diff.push_back(std::abs(a.elevation_deg[i] - ref[i]));
  std::sort(diff.begin(), diff.end());
  EXPECT_LE(diff[diff.size() / 2], 0.01);
  EXPECT_LE(diff[diff.size() * 95 / 100], 0.05);
}

TEST(ComputeHorizon, AgreesWithAFineRayMarchOnRainier) {
  HR_REQUIRE_SHARED(shared);
  CompareWithReference({"Rainier (Paradise)", {"mt_rainier_90m.tif"}, 46.7859, -121.7353}, shared);
}

TEST(ComputeHorizon, AgreesWithAFineRayMarchInTheAlps) {
  HR_REQUIRE_SHARED(shared);
  CompareWithReference({"Alps (Rhine valley)", {"N47E009.hgt"}, 47.2311, 9.5300}, shared);
}

TEST(ComputeHorizon, AgreesWithAFineRayMarchAtEverest) {
  HR_REQUIRE_SHARED(shared);
  CompareWithReference({"Everest (Gorak Shep)", {"mt_everest_90m.tif"}, 27.9806, 86.8286}, shared);
}

TEST(ComputeHorizon, AgreesWithAFineRayMarchOnAProjectedDem) {
  HR_REQUIRE_SHARED(shared);
  CompareWithReference({"Crater Lake (UTM, VTP BT)", {"crater_0513.bt"}, 42.9446, -122.1690}, shared);
}

TEST(ComputeHorizon, AgreesWithAFineRayMarchAcrossATileEdge) {
  HR_REQUIRE_SHARED(shared);
  CompareWithReference({"Pyrenees (mosaic)", {"N41E001.hgt", "N42E001.hgt"}, 42.02, 1.45}, shared);
}

TEST(ComputeHorizon, RidgeOnTheNextTileIsNotLost) {
  HR_REQUIRE_SHARED(shared);
  const std::string south = (shared / "dem" / "N41E001.hgt").string(),
                    north = (shared / "dem" / "N42E001.hgt").string();
  const double lat = 41.98, lon = 1.45;  // just south of the tile edge
  HorizonOptions o;
  const TerrainWindow one = Terrain({south}).ReadWindow({lat, lon, 0}, o.max_distance_m);
  const TerrainWindow both = Terrain({south, north}).ReadWindow({lat, lon, 0}, o.max_distance_m);
  const GeodeticPoint obs = ResolveObserver(both, lat, lon, 1.7, std::nullopt);
  const HorizonProfile a = ComputeHorizon(one, obs, o), b = ComputeHorizon(both, obs, o);
  double gain = 0;
  for (int i = 0; i < a.size(); ++i) {
    if (std::isfinite(a.elevation_deg[i])) {
      EXPECT_GE(b.elevation_deg[i], a.elevation_deg[i] - 1e-9);
    }
    const double az = a.AzimuthDeg(i);
    if ((az < 60 || az > 300) && std::isfinite(a.elevation_deg[i]))
      gain = std::max(gain, b.elevation_deg[i] - a.elevation_deg[i]);
  }
  EXPECT_GT(gain, 0.5);  // the Pyrenean main ridge to the north, on N42E001
}

TEST(ComputeHorizon, EveryDemInSharedGivesA1440BinHorizonFromItsCentre) {
  HR_REQUIRE_SHARED(shared);
  for (const auto& entry : std::filesystem::directory_iterator(shared / "dem")) {
    if (entry.path().extension() == ".md" || entry.path().extension() == ".xml")
      continue;  // notes, GDAL .aux.xml sidecars
    SCOPED_TRACE(entry.path().string());
    Terrain t({entry.path().string()});
    const GeodeticPoint c = t.CenterOf(0);
    HorizonOptions o;
    const TerrainWindow w = t.ReadWindow(c, o.max_distance_m);
    const HorizonProfile p = ComputeHorizon(w, ResolveObserver(w, c.lat_deg, c.lon_deg, 1.7, std::nullopt), o);
    ASSERT_EQ(p.size(), 1440);
    int valid = 0;
    for (double e : p.elevation_deg) valid += std::isfinite(e);
    // N48W125 is half missing (the sea is void there): no terrain, no horizon.
    if (entry.path().filename() == "N48W125.hgt") {
      EXPECT_GE(valid, 720);
    } else {
      EXPECT_EQ(valid, 1440);
    }
  }
}

}  // namespace
}  // namespace horizonreg
