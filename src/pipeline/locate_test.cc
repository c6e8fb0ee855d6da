// SPDX-License-Identifier: MIT
#include "pipeline/locate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>

#include "geo/geodesy.h"
#include "render/render.h"
#include "testing/flat_skyline.h"
#include "testing/near_far.h"
#include "testing/synthetic_dem.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

using locate_detail::Coarsen;
using locate_detail::MatchProfile;
using locate_detail::SkylineProfile;
using testing::FlatSkyline;

TEST(SkylineProfile, GivesEachSamplesRayElevation) {
  const int w = 800, h = 500;
  const double hfov = 50.0, f = 0.5 * w / std::tan(DegToRad(25.0));
  // Level camera, skyline through the centre: elevation 0 across.
  const locate_detail::Profile level = SkylineProfile(FlatSkyline(w, h, 0.5 * h), hfov, 0.0, 2.0);
  ASSERT_EQ(level.offset_deg.size(), 100u);
  for (double e : level.elevation_deg) EXPECT_NEAR(e, 0.0, 1e-9);
  EXPECT_NEAR(level.offset_deg.front(), -24.75, 0.02);
  EXPECT_NEAR(level.offset_deg.back(), 24.75, 0.02);
  // Pitched down 6 deg with no roll, the level horizon is the straight row
  // f tan(6 deg) above the centre: every sample reads 0, and its offsets
  // span less than the level camera's (that row's rays reach farther ahead).
  const double row = 0.5 * h - f * std::tan(DegToRad(6.0));
  const locate_detail::Profile down = SkylineProfile(FlatSkyline(w, h, row), hfov, -6.0, 2.0);
  for (double e : down.elevation_deg) EXPECT_NEAR(e, 0.0, 1e-9);
  EXPECT_GT(down.offset_deg.front(), level.offset_deg.front() + 0.05);
  // The level camera's row through the centre, seen pitched down: below the horizon.
  const locate_detail::Profile tilted = SkylineProfile(FlatSkyline(w, h, 0.5 * h), hfov, -6.0, 2.0);
  EXPECT_NEAR(tilted.elevation_deg[50], -6.0, 0.02);
  // Missing columns give NaN.
  Skyline gap = FlatSkyline(w, h, 0.5 * h);
  std::fill(gap.y.begin(), gap.y.begin() + 100, NAN);
  const locate_detail::Profile p = SkylineProfile(gap, hfov, 0.0, 2.0);
  EXPECT_TRUE(std::isnan(p.elevation_deg[0]));
  EXPECT_FALSE(std::isnan(p.elevation_deg[50]));
}

// A synthetic horizon's elevation at an azimuth (deg), and the horizon
// sampled every `step` deg around the circle.
double Ridges(double az) { return 2.0 * std::sin(DegToRad(3 * az)) + 1.5 * std::cos(DegToRad(7 * az) + 1.0); }
std::vector<double> RidgesEvery(double step) {
  std::vector<double> horizon(static_cast<size_t>(std::lround(360.0 / step)));
  for (size_t i = 0; i < horizon.size(); ++i) horizon[i] = Ridges(i * step);
  return horizon;
}

TEST(MatchProfile, FindsTheAzimuthWithPitchAndRollAsOffsets) {
  const double step = 0.1;
  const std::vector<double> horizon = RidgesEvery(step);
  const auto e = Ridges;
  locate_detail::Profile p;
  for (double off = -15.0; off <= 15.0; off += 0.5) {
    p.offset_deg.push_back(off);
    p.elevation_deg.push_back(e(123.4 + off) - 1.2 - 0.05 * off);  // pitch 1.2 deg, a roll's slope
  }
  const auto [cost, az] = MatchProfile(p, horizon, step, 0.1);
  EXPECT_NEAR(az, 123.4, 0.051);
  EXPECT_LT(cost, 1e-3);
  const auto [wrong_cost, wrong_az] = MatchProfile(p, horizon, step, 0.1, 250.0, 5.0);  // searched elsewhere only
  EXPECT_NEAR(wrong_az, 250.0, 5.01);
  EXPECT_GT(wrong_cost, 0.1);
  // Too few samples with a skyline: no answer.
  std::fill(p.elevation_deg.begin(), p.elevation_deg.begin() + 30, NAN);
  EXPECT_TRUE(std::isinf(MatchProfile(p, horizon, step, 0.1).first));
}

TEST(MatchProfile, StepsOfWholeBinsMatchTheGeneralSearch) {
  // Steps of whole bins take each sample's bin once and move it along; a
  // step a hair off a whole number of bins takes the general path. The
  // same azimuths searched (to 1e-6 deg) must give the same answers, over
  // the whole circle and in a window that wraps through north.
  const double step = 0.25;
  const std::vector<double> horizon = RidgesEvery(step);
  const auto e = Ridges;
  locate_detail::Profile p;
  for (double off = -20.3; off <= 20.0; off += 0.7) {
    p.offset_deg.push_back(off);
    p.elevation_deg.push_back(e(355.1 + off) - 0.8 + 0.03 * off + 0.2 * std::sin(off));
  }
  for (const double search_step : {0.25, 0.5, 1.0}) {
    const double general_step = search_step * (1.0 + 1e-9);
    const auto [cost, az] = MatchProfile(p, horizon, step, search_step);
    const auto [g_cost, g_az] = MatchProfile(p, horizon, step, general_step);
    EXPECT_NEAR(cost, g_cost, 1e-6) << search_step;
    EXPECT_NEAR(az, g_az, 1e-5) << search_step;
    const auto [w_cost, w_az] = MatchProfile(p, horizon, step, search_step, 3.3, 12.0);
    const auto [wg_cost, wg_az] = MatchProfile(p, horizon, step, general_step, 3.3, 12.0);
    EXPECT_NEAR(w_cost, wg_cost, 1e-6) << search_step;
    EXPECT_NEAR(w_az, wg_az, 1e-5) << search_step;
    EXPECT_NEAR(std::remainder(w_az - 355.1, 360.0), 0.0, search_step) << search_step;
  }
}

TEST(MatchProfile, TheScreenedSearchFindsTheExhaustiveBest) {
  // A long search screens the steps on every 4th sample and fully costs
  // the best eighth. Its answer must be the least full cost over every
  // step, taken here one step at a time (a window of one step is costed in
  // full), for a profile that fits nowhere exactly (noise, a misread run).
  const double step = 1.0;
  const std::vector<double> horizon = RidgesEvery(step);
  locate_detail::Profile p;
  unsigned seed = 12345;
  for (double off = -30.0; off <= 30.0; off += 1.0) {
    seed = seed * 1103515245u + 12345u;
    const double noise = 0.3 * ((seed >> 8) % 1000 / 1000.0 - 0.5);
    const double misread = std::abs(off - 12.0) < 4.0 ? 1.5 : 0.0;
    p.offset_deg.push_back(off);
    p.elevation_deg.push_back(Ridges(211.0 + off) - 0.7 + 0.02 * off + noise + misread);
  }
  const auto [cost, az] = MatchProfile(p, horizon, step, step);
  double best = INFINITY, best_az = NAN;
  for (int s = 0; s < 360; ++s) {
    const auto [c, a] = MatchProfile(p, horizon, step, step, s, 0.0);
    if (c < best) best = c, best_az = a;
  }
  EXPECT_DOUBLE_EQ(cost, best);
  EXPECT_DOUBLE_EQ(az, best_az);
  EXPECT_NEAR(az, 211.0, 1e-9);
}

TEST(Coarsen, PoolsBlocksByTheirMeanAndKeepsTheGeoreference) {
  DemGrid g = testing::SynthesizeDem(46.1, 7.9, 1.0 / 1200, 121, 121, [](double lat, double) {
    return lat > 46.05 ? 900.0 : 500.0;
  });
  const double spacing = g.SpacingM();
  TerrainWindow w = testing::WindowOf(std::move(g));
  const TerrainWindow c = Coarsen(w, 4.0 * spacing + 1.0);
  ASSERT_EQ(c.grids.size(), 1u);
  const DemGrid &a = w.grids[0], &b = c.grids[0];
  EXPECT_EQ(b.width, (a.width - 1) / 4 + 1);
  EXPECT_EQ(b.height, (a.height - 1) / 4 + 1);
  EXPECT_DOUBLE_EQ(b.LatAt(3, 5), a.LatAt(12, 20));
  EXPECT_DOUBLE_EQ(b.LonAt(3, 5), a.LonAt(12, 20));
  EXPECT_EQ(b.At(7, 0), 900.0f);
  EXPECT_EQ(b.At(7, b.height - 1), 500.0f);
  // Already that coarse: kept as it is.
  const TerrainWindow same = Coarsen(w, 0.5 * spacing);
  EXPECT_EQ(same.grids[0].width, a.width);
}

TEST(LocateOptions, RejectsBadAreas) {
  LocateOptions o;
  o.lat_deg = 46.0, o.lon_deg = 8.0;
  o.Check();
  o.radius_m = 5.0;
  EXPECT_THROW(o.Check(), InvalidArgument);
  o.radius_m = 1000.0, o.lat_deg = 95.0;
  EXPECT_THROW(o.Check(), InvalidArgument);
  o.lat_deg = 46.0, o.site.alt_m = 700.0;
  EXPECT_THROW(o.Check(), InvalidArgument);  // locate takes a height above the ground
}

TEST(Locate, FindsARenderedViewInsideTheArea) {
  const TerrainWindow window = testing::NearFarWindow();
  const GeodeticPoint eye =
      ResolveObserver(window, testing::kNearFarLat, testing::kNearFarLon, 1.7, std::nullopt);
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(640, 400, 60.0);
  const CameraPose truth{225.0, 1.0, 0.5};  // towards the far cones (the near hills change within a grid step)
  RenderOptions rop;
  rop.max_distance_m = 12'000.0;
  const cv::Mat photo = RenderView(window, eye, truth, k, rop);
  LocateOptions o;
  const GeodeticPoint centre = LocalFrame(eye).GeodeticFromEnu({500.0, -300.0, 0.0});
  o.lat_deg = centre.lat_deg, o.lon_deg = centre.lon_deg;
  o.radius_m = 900.0;
  o.grid_m = 100.0;
  o.coarse_max_distance_m = 12'000.0;
  o.site.agl_m = 1.7;
  o.site.max_distance_m = 12'000.0;
  o.photo.pinhole = true;
  o.photo.hfov_deg = 60.0;
  o.photo.skyline = testing::ExactSkyline(window, eye, truth, k, 12'000.0);  // the extractor is tested elsewhere
  ThreadPool pool(2);
  const LocateResult r = LocateInWindow(window, photo, o, &pool);
  std::ostringstream seen;
  for (const LocateCandidate& c : r.candidates)
    seen << "\n  " << LocalFrame(eye).EnuFromGeodetic({c.lat_deg, c.lon_deg, eye.height_m}).head<2>().norm()
         << " m: profile " << c.cost << ", " << (c.tried ? c.message : "not registered") << " (misfit " << c.misfit
         << ")";
  ASSERT_TRUE(r.located) << r.message << seen.str();
  ASSERT_FALSE(r.candidates.empty());
  const Eigen::Vector3d at =
      LocalFrame(eye).EnuFromGeodetic({r.candidates[0].lat_deg, r.candidates[0].lon_deg, eye.height_m});
  EXPECT_LT(at.head<2>().norm(), 30.0);
  ASSERT_TRUE(r.registration.registration.registered);
  EXPECT_NEAR(AngDiffDeg(r.registration.registration.pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.3);
  EXPECT_NEAR(r.registration.registration.pose.pitch_deg, truth.pitch_deg, 0.3);
  EXPECT_GT(r.coarse_viewpoints, 200);
  EXPECT_GE(r.registration_distinctiveness, o.min_distinctiveness);
  const double nats = r.registration.registration.evidence_nats;
  EXPECT_GE(nats, o.min_evidence_nats);

  // The same search, asked for more evidence than the answer carries: no
  // answer, and the reason.
  o.min_evidence_nats = nats + 1.0;
  const LocateResult strict = LocateInWindow(window, photo, o, &pool);
  EXPECT_FALSE(strict.located);
  EXPECT_NE(strict.message.find("too little evidence"), std::string::npos) << strict.message;
}

}  // namespace
}  // namespace horizonreg
