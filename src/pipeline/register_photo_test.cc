// SPDX-License-Identifier: MIT
#include "pipeline/register_photo.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <opencv2/core.hpp>
#include <thread>

#include "match/predicted.h"
#include "pipeline/report.h"
#include "render/render.h"
#include "testing/cone_ring.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

SiteOptions RingSiteOptions() {
  SiteOptions o;
  o.agl_m = 1.7;
  o.max_distance_m = 30'000.0;
  return o;
}

TEST(Site, HoldsTheRegistrationHorizonAndComputesRidgesOnceAcrossThreads) {
  testing::ConeRing ring = testing::MakeConeRing();
  ThreadPool pool(2);
  const Site site(ring.window, 46.0, 8.0, RingSiteOptions(), &pool);
  ASSERT_EQ(site.horizon().size(), ring.horizon.size());  // 0.1 deg bins
  for (int i = 0; i < site.horizon().size(); i += 97)
    EXPECT_DOUBLE_EQ(site.horizon().elevation_deg[i], ring.horizon.elevation_deg[i]) << i;
  EXPECT_NEAR(site.EyeAboveGroundM(), 1.7, 1e-6);
  const std::vector<std::vector<Ridge>>* seen[2] = {nullptr, nullptr};
  std::thread a([&] { seen[0] = &site.ridges(); }), b([&] { seen[1] = &site.ridges(); });
  a.join();
  b.join();
  EXPECT_EQ(seen[0], seen[1]);
  EXPECT_EQ(seen[0]->size(), static_cast<size_t>(site.horizon().size()));
}

TEST(Site, RejectsBadPositionsAndOptions) {
  testing::ConeRing ring = testing::MakeConeRing();
  EXPECT_THROW(Site(ring.window, 95.0, 8.0, RingSiteOptions()), InvalidArgument);
  SiteOptions both = RingSiteOptions();
  both.alt_m = 900.0;
  EXPECT_THROW(Site(ring.window, 46.0, 8.0, both), InvalidArgument);
  SiteOptions step = RingSiteOptions();
  step.azimuth_step_deg = 0.7;  // 360 / step not whole
  EXPECT_THROW(Site(ring.window, 46.0, 8.0, step), InvalidArgument);
  EXPECT_THROW(Site({"/nonexistent/dem.tif"}, 46.0, 8.0, RingSiteOptions()), Error);
}

TEST(ResolvePhotoPosition, ArgumentsThenSensorsThenExif) {
  SensorReading sensors, exif;
  exif.lat_deg = 1.0, exif.lon_deg = 2.0, exif.alt_m = 300.0;
  PhotoPosition p = ResolvePhotoPosition(std::nullopt, std::nullopt, std::nullopt, std::nullopt, sensors, exif, "a.jpg");
  EXPECT_EQ(p.source, "exif");
  EXPECT_EQ(p.lat_deg, 1.0);
  EXPECT_EQ(p.alt_m, 300.0);
  sensors.lat_deg = 3.0, sensors.lon_deg = 4.0, sensors.agl_m = 10.0;
  p = ResolvePhotoPosition(std::nullopt, std::nullopt, std::nullopt, std::nullopt, sensors, exif, "a.jpg");
  EXPECT_EQ(p.source, "sensors");
  EXPECT_EQ(p.agl_m, 10.0);
  EXPECT_FALSE(p.alt_m);
  p = ResolvePhotoPosition(5.0, 6.0, std::nullopt, 12.0, sensors, exif, "a.jpg");
  EXPECT_EQ(p.source, "arguments");
  EXPECT_EQ(p.lon_deg, 6.0);
  EXPECT_FALSE(p.agl_m);
  EXPECT_EQ(p.alt_m, 12.0);
  try {
    ResolvePhotoPosition(std::nullopt, std::nullopt, std::nullopt, std::nullopt, {}, {}, "b.jpg");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'b.jpg'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ResolvePhotoPosition(5.0, std::nullopt, std::nullopt, std::nullopt, {}, {}, "c.jpg"), InvalidArgument);
  EXPECT_THROW(ResolvePhotoPosition(95.0, 6.0, std::nullopt, std::nullopt, {}, {}, "c.jpg"), InvalidArgument);
}

TEST(ParseInitialPose, ReadsFourAnglesAndNamesBadText) {
  const InitialPose p = ParseInitialPose("10.5,-2,0.5,48");
  EXPECT_EQ(p.azimuth_deg, 10.5);
  EXPECT_EQ(p.pitch_deg, -2.0);
  EXPECT_EQ(p.hfov_deg, 48.0);
  for (const char* bad : {"", "1,2,3", "1,2,3,4,5", "1,2,3,200", "1,95,0,40", "a,b,c,d", "1,2,3,40x"})
    EXPECT_THROW(ParseInitialPose(bad), InvalidArgument) << bad;
  EXPECT_EQ(ParseHfovRange("30:60"), std::make_pair(30.0, 60.0));
  for (const char* bad : {"30", "60:30", "0:10", "30:60x", "30:170"}) EXPECT_THROW(ParseHfovRange(bad), InvalidArgument) << bad;
}

TEST(PhotoRegistrationOptions, OpeningAngleWindowAndErrorModelBySource) {
  testing::ConeRing ring = testing::MakeConeRing();
  const Site site(ring.window, 46.0, 8.0, RingSiteOptions());
  PhotoOptions po;
  std::string fov;
  RegistrationOptions ro = PhotoRegistrationOptions(site, po, 600, 400, &fov);
  EXPECT_EQ(fov, "default");
  EXPECT_EQ(ro.min_hfov_deg, RegistrationOptions{}.min_hfov_deg);
  EXPECT_EQ(ro.dem_error.position_sigma_m, 1.0);  // coordinates given: surveyed
  EXPECT_EQ(ro.dem_error.height_sigma_m, 2.0);    // a height above the DEM
  po.exif.focal_35mm = 35.0;
  po.exif.compass_deg = 120.0;
  po.position_source = "exif";
  ro = PhotoRegistrationOptions(site, po, 600, 400, &fov);
  EXPECT_EQ(fov, "exif");
  const double h = HfovFromFocal35mm(35.0, 600, 400);
  EXPECT_NEAR(ro.min_hfov_deg, 0.9 * h, 1e-9);
  EXPECT_NEAR(ro.max_hfov_deg, 1.1 * h, 1e-9);
  EXPECT_EQ(ro.dem_error.position_sigma_m, 10.0);  // a phone's GPS
  ASSERT_TRUE(ro.prior.compass_deg);
  EXPECT_EQ(*ro.prior.compass_deg, 120.0);
  EXPECT_EQ(ro.prior.compass_sigma_deg, 20.0);
  po.hfov_deg = 40.0;
  ro = PhotoRegistrationOptions(site, po, 600, 400, &fov);
  EXPECT_EQ(fov, "--hfov");
  EXPECT_NEAR(ro.min_hfov_deg, 38.8, 1e-9);
  po.hfov_range_deg = std::make_pair(30.0, 50.0);
  EXPECT_THROW(PhotoRegistrationOptions(site, po, 600, 400), InvalidArgument);  // both
}

// A view of the cone ring rendered from its centre, as a photo.
struct RenderedRing {
  testing::ConeRing ring = testing::MakeConeRing();
  ThreadPool pool{2};
  Site site{ring.window, 46.0, 8.0, RingSiteOptions(), &pool};
  CameraPose truth{40.0, 1.5, -0.8};
  cv::Mat photo = Render();
  cv::Mat Render() const {
    RenderOptions ro;
    ro.max_distance_m = 30'000.0;
    return RenderView(ring.window, ring.eye, truth, CameraIntrinsics::FromHfov(480, 320, 50.0), ro);
  }
};

TEST(UnknownFovHint, NamesBothOpeningAnglesOnlyWhenTheyDifferAndNoneWasKnown) {
  constexpr int kWidth = 1000;
  Registration r;
  r.registered = false;
  r.focal_px = FocalFromHfovPx(52.0, kWidth);
  PoseCandidate rival;
  rival.focal_px = FocalFromHfovPx(21.0, kWidth);
  r.rival = rival;
  const std::string hint = UnknownFovHint(r, "default", kWidth);
  EXPECT_NE(hint.find("--hfov"), std::string::npos) << hint;
  EXPECT_NE(hint.find("52 deg"), std::string::npos) << hint;
  EXPECT_NE(hint.find("21 deg"), std::string::npos) << hint;
  EXPECT_EQ(UnknownFovHint(r, "exif", kWidth), "");  // the angle was known
  r.rival->focal_px = FocalFromHfovPx(48.0, kWidth);
  EXPECT_EQ(UnknownFovHint(r, "default", kWidth), "");  // a rival at the same angle: no help from --hfov
  r.rival->focal_px = FocalFromHfovPx(21.0, kWidth);
  r.registered = true;
  EXPECT_EQ(UnknownFovHint(r, "default", kWidth), "");
  r.registered = false;
  r.rival.reset();
  EXPECT_EQ(UnknownFovHint(r, "default", kWidth), "");
}

TEST(RegisterPhoto, RegistersARenderedViewAndReportsIt) {
  RenderedRing scene;
  const Site& site = scene.site;
  const CameraPose truth = scene.truth;
  const cv::Mat& photo = scene.photo;
  ThreadPool& pool = scene.pool;
  PhotoOptions po;
  po.pinhole = true;
  const PhotoRegistration r = RegisterPhoto(site, photo, po, &pool);
  ASSERT_TRUE(r.registration.registered) << r.registration.message;
  EXPECT_NEAR(AngDiffDeg(r.registration.pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.1);
  EXPECT_NEAR(r.registration.pose.pitch_deg, truth.pitch_deg, 0.1);
  EXPECT_NEAR(r.registration.hfov_deg, 50.0, 1.0);
  // The same photo refined from a pose 2 deg off, and without a pool.
  po.initial = InitialPose{42.0, 1.5, -0.8, 50.0};
  const PhotoRegistration again = RegisterPhoto(site, photo, po);
  ASSERT_TRUE(again.registration.registered) << again.registration.message;
  EXPECT_NEAR(AngDiffDeg(again.registration.pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.1);
  const nlohmann::json j = RegistrationReport(site, r, "arguments", 12.0);
  EXPECT_EQ(j["status"], "registered");
  EXPECT_EQ(j["width"], 480);
  EXPECT_EQ(j["observer"]["source"], "arguments");
  EXPECT_NEAR(j["azimuth_deg"].get<double>(), r.registration.pose.azimuth_deg, 1e-4);
  EXPECT_EQ(j["timing_ms"]["total"], 12.0);
  const cv::Mat drawn = DrawRegistration(site, photo, r, "");
  EXPECT_EQ(drawn.size(), photo.size());
  // A uniform grey frame: no_match with a reason, never an exception.
  const PhotoRegistration none = RegisterPhoto(site, cv::Mat(320, 480, CV_8UC3, cv::Scalar(128, 128, 128)), {}, &pool);
  EXPECT_FALSE(none.registration.registered);
  EXPECT_FALSE(none.registration.message.empty());
  EXPECT_EQ(RegistrationReport(site, none, "arguments", 1.0)["azimuth_deg"], nullptr);
  EXPECT_THROW(RegisterPhoto(site, cv::Mat(4, 4, CV_8UC3), {}), InvalidArgument);
}

TEST(ConfirmedWithoutPrior, TheSearchWithNoPriorDecidesAndThePoseGivenVetoes) {
  RegistrationOptions constrained;
  constrained.prior.compass_deg = 60.0, constrained.prior.pitch_deg = -4.0, constrained.prior.roll_deg = 1.5;
  constrained.prior.compass_sigma_deg = constrained.prior.inclinometer_sigma_deg = 2.0;  // gate +-6 deg
  constrained.min_hfov_deg = 47.5, constrained.max_hfov_deg = 52.5;                     // 50 deg +-5%
  Registration alone;
  alone.focal_px = 500.0, alone.hfov_deg = 50.5;
  // Refused alone (a rival elsewhere fits almost as well): refused, saying
  // why and what would let the pose given decide.
  alone.registered = false, alone.message = "ambiguous: another pose fits almost as well (cost ratio 1.1)";
  Registration r = ConfirmedWithoutPrior(alone, constrained);
  EXPECT_FALSE(r.registered);
  EXPECT_NE(r.message.find("cost ratio 1.1"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("--trust-position"), std::string::npos) << r.message;
  // Registered inside the gate: the answer, confirmed.
  alone.registered = true, alone.message = "registered", alone.pose = {64.0, -4.2, 1.4};
  r = ConfirmedWithoutPrior(alone, constrained);
  EXPECT_TRUE(r.registered);
  EXPECT_DOUBLE_EQ(r.pose.azimuth_deg, 64.0);
  EXPECT_NE(r.message.find("confirmed"), std::string::npos) << r.message;
  // Registered 8 deg off in azimuth, or 9 deg off in pitch, or at a 60 deg
  // opening angle: outside the pose given, refused.
  for (const auto& [pose, hfov] : {std::pair{CameraPose{68.5, -4.0, 1.5}, 50.5},
                                   std::pair{CameraPose{60.0, 5.0, 1.5}, 50.5},
                                   std::pair{CameraPose{60.0, -4.0, 1.5}, 60.0}}) {
    alone.pose = pose, alone.hfov_deg = hfov;
    r = ConfirmedWithoutPrior(alone, constrained);
    EXPECT_FALSE(r.registered) << pose.azimuth_deg << " " << pose.pitch_deg << " " << hfov;
    EXPECT_NE(r.message.find("outside the pose given"), std::string::npos) << r.message;
  }
}

TEST(RegisterPhoto, AnInitialPoseIsConfirmedOrTrusted) {
  RenderedRing scene;
  PhotoOptions po;
  po.pinhole = true;
  po.initial = InitialPose{42.0, 1.5, -0.8, 50.0};
  for (const bool trusted : {false, true}) {
    if (trusted) po.check_position.reset();
    const PhotoRegistration r = RegisterPhoto(scene.site, scene.photo, po, &scene.pool);
    ASSERT_TRUE(r.registration.registered) << r.registration.message;
    EXPECT_NEAR(AngDiffDeg(r.registration.pose.azimuth_deg, scene.truth.azimuth_deg), 0.0, 0.1);
    EXPECT_EQ(r.registration.message.find("confirmed") != std::string::npos, !trusted) << r.registration.message;
  }
}

TEST(PositionCheck, PassesTheTruePositionAndRefusesOneTwoKilometresOff) {
  RenderedRing scene;
  const Site& site = scene.site;
  const cv::Mat& photo = scene.photo;
  ThreadPool& pool = scene.pool;
  testing::ConeRing& ring = scene.ring;
  PhotoOptions po;
  po.pinhole = true;
  const PhotoRegistration r = RegisterPhoto(site, photo, po, &pool);
  ASSERT_TRUE(r.registration.registered) << r.registration.message;
  ASSERT_TRUE(r.position_check.has_value());
  EXPECT_TRUE(r.position_check->consistent);
  EXPECT_GE(r.position_check->cost_ratio, 0.95);
  // The given place and the first ring of 8; no place there fits better or
  // nearly as well, so no far ring and no wide look.
  EXPECT_EQ(r.position_check->cost_ratio, 1.0);
  EXPECT_EQ(r.position_check->horizons, 9);
  EXPECT_EQ(r.position_check->wide_places, 0);
  EXPECT_EQ(RegistrationReport(site, r, "arguments", 1.0)["position_check"]["consistent"], true);
  // The best place is the given one: the orientation does not move.
  EXPECT_EQ(r.position_check->AzimuthShiftDeg(), 0.0);
  EXPECT_EQ(RegistrationReport(site, r, "arguments", 1.0)["position_check"]["best_azimuth_shift_deg"], 0.0);
  // Trusted: no check.
  po.check_position.reset();
  EXPECT_FALSE(RegisterPhoto(site, photo, po, &pool).position_check.has_value());

  // The same skyline and pose judged from 2 km east of the truth: a place
  // towards the truth fits clearly better.
  const GeodeticPoint east = LocalFrame(site.observer()).GeodeticFromEnu(Eigen::Vector3d(2000.0, 0.0, 0.0));
  const Site wrong(ring.window, east.lat_deg, east.lon_deg, RingSiteOptions(), &pool);
  RegistrationOptions options = r.options;
  const PositionCheck c = CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options,
                                                   PositionCheckOptions{}, &pool);
  EXPECT_FALSE(c.consistent);
  EXPECT_LT(c.cost_ratio, 0.9);
  EXPECT_GE(c.OffsetM(), 500.0);
  EXPECT_GE(c.horizons, 17);  // the cost falls on the first ring: the far ring too
  EXPECT_NEAR(AngDiffDeg(c.BearingDeg(), 270.0), 0.0, 50.0);
  EXPECT_NE(c.message.find("position"), std::string::npos);
  // The orientation at each place: at the given one, the wrong position's
  // own (moved off the truth's by the 2 km of parallax); at the best place,
  // which lies towards the truth, nearer the truth's.
  const double truth_az = r.registration.pose.azimuth_deg;
  EXPECT_GT(std::abs(AngDiffDeg(c.given_pose.azimuth_deg, truth_az)), 3.0);
  EXPECT_LT(std::abs(AngDiffDeg(c.best_pose.azimuth_deg, truth_az)),
            std::abs(AngDiffDeg(c.given_pose.azimuth_deg, truth_az)) - 1.0);
  EXPECT_GT(c.AzimuthShiftDeg() * AngDiffDeg(truth_az, c.given_pose.azimuth_deg), 0.0);
  EXPECT_NEAR(c.PitchShiftDeg(), 0.0, 0.5);  // the cones' tops stand level around the truth
  // Without a pool: the same answer.
  const PositionCheck serial = CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options,
                                                        PositionCheckOptions{}, nullptr);
  EXPECT_EQ(serial.consistent, c.consistent);
  EXPECT_DOUBLE_EQ(serial.cost_ratio, c.cost_ratio);
  PositionCheckOptions bad;
  bad.max_cost_ratio = 1.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
  bad = PositionCheckOptions{};
  bad.wide_spacing_m = 0.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
  bad = PositionCheckOptions{};
  bad.wide_trigger = 1.5;
  EXPECT_THROW(bad.Check(), InvalidArgument);
  bad = PositionCheckOptions{};
  bad.max_cost_ratio_ridges = 0.8;  // looser than the plain limit
  EXPECT_THROW(bad.Check(), InvalidArgument);
  bad = PositionCheckOptions{};
  bad.wide_radius_ridges_m = -1.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
  // A registration the inner ridges decided is held to the stricter limit:
  // with the plain limit under the ratio found and the ridges' limit over
  // it, the same check passes it, and refuses it once the ridges decided.
  if (c.cost_ratio < 1.0) {
    PositionCheckOptions ridges;
    ridges.max_cost_ratio = 0.5 * c.cost_ratio;
    ridges.max_cost_ratio_ridges = std::min(0.99, 1.5 * c.cost_ratio);
    EXPECT_TRUE(CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options, ridges, &pool)
                    .consistent);
    ridges.ridges_decided = true;
    const PositionCheck by_ridges =
        CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options, ridges, &pool);
    EXPECT_FALSE(by_ridges.consistent);
    EXPECT_TRUE(by_ridges.only_ridges_limit);
    EXPECT_FALSE(by_ridges.only_lens_limit);
    // So is one whose opening angle departs from its EXIF's by 6% or more:
    // refused under the same limit, and the refusal names the position, not
    // the pose. Up to 4% the plain limit holds; in between, a limit between.
    PositionCheckOptions lens = ridges;
    lens.ridges_decided = false;
    lens.lens_departure = 0.07;
    EXPECT_DOUBLE_EQ(lens.MaxCostRatio(), lens.max_cost_ratio_ridges);
    const PositionCheck by_lens =
        CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options, lens, &pool);
    EXPECT_FALSE(by_lens.consistent);
    EXPECT_TRUE(by_lens.only_lens_limit);
    EXPECT_FALSE(by_lens.only_ridges_limit);
    EXPECT_NE(by_lens.message.find("EXIF"), std::string::npos);
    lens.lens_departure = 0.03;
    EXPECT_DOUBLE_EQ(lens.MaxCostRatio(), lens.max_cost_ratio);
    EXPECT_TRUE(CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, options, lens, &pool)
                    .consistent);
    lens.lens_departure = 0.05;
    EXPECT_NEAR(lens.MaxCostRatio(), 0.5 * (lens.max_cost_ratio + lens.max_cost_ratio_ridges), 1e-12);
    lens.lens_departure = -0.01;
    EXPECT_THROW(lens.Check(), InvalidArgument);
  }
}

TEST(LensDepartureFromExif, TheFittedOpeningAngleAgainstTheExifsOwn) {
  PhotoOptions po;
  Registration r;
  const double h = HfovFromFocal35mm(35.0, 600, 400);
  r.focal_px = FocalFromHfovPx(1.06 * h, 600);
  EXPECT_FALSE(PhotoExifHfovDeg(po, 600, 400).has_value());  // no EXIF: nothing to depart from
  EXPECT_EQ(LensDepartureFromExif(po, r, 600, 400), 0.0);
  po.exif.focal_35mm = 35.0;
  ASSERT_TRUE(PhotoExifHfovDeg(po, 600, 400).has_value());
  EXPECT_NEAR(*PhotoExifHfovDeg(po, 600, 400), h, 1e-9);
  EXPECT_NEAR(LensDepartureFromExif(po, r, 600, 400), 0.06, 1e-9);
  r.focal_px = FocalFromHfovPx(0.94 * h, 600);  // narrower counts alike
  EXPECT_NEAR(LensDepartureFromExif(po, r, 600, 400), 0.06, 1e-9);
  r.focal_px = FocalFromHfovPx(1.06 * h, 600);
  po.hfov_deg = 1.06 * h;  // an opening angle given: the EXIF's is not searched
  EXPECT_EQ(LensDepartureFromExif(po, r, 600, 400), 0.0);
  po.hfov_deg.reset();
  po.camera = CameraIntrinsics::FromHfov(600, 400, 1.06 * h);  // a known camera is used as given
  EXPECT_EQ(LensDepartureFromExif(po, r, 600, 400), 0.0);
  po.camera.reset();
  r.focal_px = NAN;  // no pose fitted
  EXPECT_EQ(LensDepartureFromExif(po, r, 600, 400), 0.0);
}

// Given no altitude (the ring's site stands 1.7 m over the ground) and a
// known opening angle, the wide look is taken even where the first ring
// shows a clear bowl; with an altitude, or with the opening angle searched,
// it is not (wide_when_unpinned).
TEST(PositionCheck, NoAltitudeAndAKnownOpeningAngleTakeTheWideLook) {
  RenderedRing scene;
  PhotoOptions po;
  po.pinhole = true;
  po.hfov_deg = 50.0;
  const PhotoRegistration r = RegisterPhoto(scene.site, scene.photo, po, &scene.pool);
  ASSERT_TRUE(r.registration.registered) << r.registration.message;
  ASSERT_TRUE(r.options.OpeningAngleKnown());
  ASSERT_TRUE(r.position_check.has_value());
  EXPECT_TRUE(r.position_check->consistent);
  EXPECT_GT(r.position_check->wide_places, 90);
  PositionCheckOptions co;
  co.wide_when_unpinned = false;
  EXPECT_EQ(CheckPositionConsistency(scene.site, scene.site.horizon(), r.skyline, r.registration, r.options, co,
                                     &scene.pool)
                .wide_places,
            0);
  // The opening angle searched (10-120 deg): the first ring decides, as above.
  RegistrationOptions wide = r.options;
  wide.min_hfov_deg = 10.0;
  wide.max_hfov_deg = 120.0;
  EXPECT_FALSE(wide.OpeningAngleKnown());
  EXPECT_EQ(CheckPositionConsistency(scene.site, scene.site.horizon(), r.skyline, r.registration, wide,
                                     PositionCheckOptions{}, &scene.pool)
                .wide_places,
            0);
}

TEST(PositionCheck, TheWideLookReachesABowlThePatternCannot) {
  // From 2.5 km east of the truth with no far ring and no walk (the pattern
  // stops after the first ring, as it does where a wrong position sits in
  // a shallow bowl of its own), and a limit the first ring's best place
  // (1 km towards the truth) does not pass: the wide look's grid reaches
  // the truth's bowl and refuses.
  RenderedRing scene;
  PhotoOptions po;
  po.pinhole = true;
  const PhotoRegistration r = RegisterPhoto(scene.site, scene.photo, po, &scene.pool);
  ASSERT_TRUE(r.registration.registered) << r.registration.message;
  const GeodeticPoint east = LocalFrame(scene.site.observer()).GeodeticFromEnu(Eigen::Vector3d(2500.0, 0.0, 0.0));
  const Site wrong(scene.ring.window, east.lat_deg, east.lon_deg, RingSiteOptions(), &scene.pool);
  PositionCheckOptions co;
  co.far_ring_m = 0.0;
  co.max_horizons = 9;  // the given place and the first ring: no walk
  co.wide_radius_m = 0.0;
  const PositionCheck first =
      CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, r.options, co, &scene.pool);
  EXPECT_EQ(first.wide_places, 0);
  EXPECT_EQ(first.horizons, 9);
  EXPECT_NEAR(first.OffsetM(), 1000.0, 1.0);
  ASSERT_LT(first.cost_ratio, 1.0);
  co.max_cost_ratio = 0.5 * first.cost_ratio;
  const PositionCheck narrow =
      CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, r.options, co, &scene.pool);
  EXPECT_TRUE(narrow.consistent) << narrow.message;
  co.wide_radius_m = 3500.0;
  const PositionCheck wide =
      CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, r.options, co, &scene.pool);
  EXPECT_GT(wide.wide_places, 0);
  EXPECT_FALSE(wide.consistent);
  EXPECT_LT(wide.cost_ratio, co.max_cost_ratio);
  EXPECT_NEAR(wide.OffsetM(), 2500.0, 400.0);
  EXPECT_NEAR(AngDiffDeg(wide.BearingDeg(), 270.0), 0.0, 10.0);
  // The grid is fitted nearest first until a place passes the limit: with
  // a limit nothing passes, all of it (the disc 1.3-3.5 km at 600 m: about
  // 100 places), and the same best place.
  PositionCheckOptions strict = co;
  strict.max_cost_ratio = 1e-6;
  const PositionCheck all =
      CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, r.options, strict, &scene.pool);
  EXPECT_TRUE(all.consistent);
  EXPECT_GT(all.wide_places, 90);
  EXPECT_LT(wide.wide_places, all.wide_places);
  EXPECT_NEAR(all.OffsetM(), 2500.0, 400.0);
  // Never (wide_trigger -1): the first ring's answer.
  co.wide_trigger = -1.0;
  EXPECT_EQ(CheckPositionConsistency(wrong, wrong.horizon(), r.skyline, r.registration, r.options, co, &scene.pool)
                .wide_places,
            0);
}

// The cone ring as a flat-coloured photo whose skyline
// extraction missed a snow field: in the left 30% of the columns the extracted
// boundary lies 25 px low, at the snow's lower edge.
class GuidedSkylineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    horizon = testing::MakeConeRing().horizon;
    truth_y = PredictedSkyline(horizon, truth, k);
    image = cv::Mat(k.height, k.width, CV_8UC3, kSky);
    skyline.width = k.width;
    skyline.height = k.height;
    skyline.y = truth_y;
    skyline.confidence.assign(k.width, 1.0);
    for (int c = 0; c < k.width; ++c) {
      const bool snow = c < k.width * 30 / 100;
      const int top = static_cast<int>(std::lround(truth_y[c]));
      for (int r = std::max(0, top); r < k.height; ++r)
        image.at<cv::Vec3b>(r, c) = r < top + 25 && snow ? kSnow : cv::Vec3b(60, 110, 70);
      if (snow) skyline.y[c] = top + 25.0;
    }
  }
  // The second look at `first` (the image's near miss) registers at the
  // true pose, fitting nearly every column.
  void ExpectTheSecondLookRegistersTheTruth(const Registration& first) const {
    const auto again = RecheckWithGuidedSkyline(image, skyline, horizon, first, RegistrationOptions{});
    ASSERT_TRUE(again);
    ASSERT_TRUE(again->registered) << again->message;
    EXPECT_NEAR(AngDiffDeg(again->pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.05);
    EXPECT_NEAR(again->pose.pitch_deg, truth.pitch_deg, 0.05);
    EXPECT_GE(again->inlier_fraction, 0.95);
  }
  const cv::Vec3b kSky{230, 200, 170}, kSnow{235, 235, 235};  // BGR
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(480, 320, 50.0);
  const CameraPose truth{25.0, 2.0, 0.5};
  HorizonProfile horizon;
  std::vector<double> truth_y;  // the horizon projected at the true pose
  cv::Mat image;
  Skyline skyline;
};

TEST_F(GuidedSkylineTest, ANearMissBecomesARegistrationAtTheTruePose) {
  const Registration first = Register(skyline, horizon, RegistrationOptions{});
  ASSERT_FALSE(first.registered) << first.message;  // 70% fit, and the misread columns leave it ambiguous
  ASSERT_GE(first.inlier_fraction, RegistrationOptions{}.min_inlier_fraction - 0.2) << first.message;
  ASSERT_NO_FATAL_FAILURE(ExpectTheSecondLookRegistersTheTruth(first));
  EXPECT_TRUE(RegisterImage(image, skyline, horizon, RegistrationOptions{}).registered);
}

// A real snow ridge under a hazy sky fades from sky to snow over several
// rows: the rows just above the step are still the transition, and the sky
// is read further up.
TEST_F(GuidedSkylineTest, ASoftSnowEdgeIsReadToo) {
  const cv::Vec3d sky(kSky), snow(kSnow);
  for (int c = 0; c < k.width * 30 / 100; ++c) {
    const int top = static_cast<int>(std::lround(truth_y[c]));
    for (int i = 0; i < 6; ++i) {  // rows top - 3 .. top + 2 from sky to snow
      const int r = top - 3 + i;
      if (r < 0 || r >= k.height) continue;
      const cv::Vec3d v = sky + (snow - sky) * ((i + 0.5) / 6.0);
      image.at<cv::Vec3b>(r, c) = cv::Vec3b(cv::saturate_cast<uint8_t>(v[0]), cv::saturate_cast<uint8_t>(v[1]),
                                            cv::saturate_cast<uint8_t>(v[2]));
    }
  }
  const Registration first = Register(skyline, horizon, RegistrationOptions{});
  ASSERT_FALSE(first.registered) << first.message;
  ASSERT_NO_FATAL_FAILURE(ExpectTheSecondLookRegistersTheTruth(first));
}

// A far range in haze: a step of 8-12 over a smooth sky (BGR distance of
// 3-row means), which the extraction nulled. After a faint miss the second
// look reads those columns too, where the DEM horizon predicts them; a step
// of 6 is not read, nor a step of 11.5 under a sky whose own rows step by 7.
TEST_F(GuidedSkylineTest, AFaintRangeTheExtractionNulledIsReadNearThePrediction) {
  auto faint_copy = [&](const cv::Vec3b& below) {
    cv::Mat faint = image.clone();
    for (int c = 0; c < k.width * 30 / 100; ++c) {
      const int top = static_cast<int>(std::lround(truth_y[c]));
      for (int r = std::max(0, top); r < k.height; ++r) faint.at<cv::Vec3b>(r, c) = below;
    }
    return faint;
  };
  Skyline nulled = skyline;
  for (int c = 0; c < k.width * 30 / 100; ++c) nulled.y[c] = NAN, nulled.confidence[c] = 0.0;
  // A faint miss, as the photo's first look gives it: 40% of the skyline
  // fits (the rest read low or not at all), 0.2-0.3 short of the gate.
  Registration first = Register(nulled, horizon, RegistrationOptions{});
  ASSERT_GT(first.focal_px, 0.0);
  first.registered = false;
  first.inlier_fraction = RegistrationOptions{}.min_inlier_fraction - 0.25;
  const cv::Mat hazy = faint_copy(cv::Vec3b(kSky[0] - 9, kSky[1] - 6, kSky[2] - 4));  // 11.5
  // A near miss (within 0.2 of the gate) is read as before: nulled columns
  // stay null, so nothing is re-read here; 0.3 short or more, no second look.
  Registration near = first;
  near.inlier_fraction = RegistrationOptions{}.min_inlier_fraction - 0.15;
  EXPECT_FALSE(RecheckWithGuidedSkyline(hazy, nulled, horizon, near, RegistrationOptions{}));
  // Most of the skyline fitting but ambiguous at 0.8-0.85 of the gate: no
  // hazy photo, no second look.
  Registration ambiguous = near;
  ambiguous.ambiguity_ratio = 0.82 * RegistrationOptions{}.min_ambiguity_ratio;
  EXPECT_FALSE(RecheckWithGuidedSkyline(hazy, nulled, horizon, ambiguous, RegistrationOptions{}));
  Registration far = first;
  far.inlier_fraction = RegistrationOptions{}.min_inlier_fraction - 0.35;
  EXPECT_FALSE(RecheckWithGuidedSkyline(hazy, nulled, horizon, far, RegistrationOptions{}));
  const auto again = RecheckWithGuidedSkyline(hazy, nulled, horizon, first, RegistrationOptions{});
  ASSERT_TRUE(again);
  ASSERT_TRUE(again->registered) << again->message;
  EXPECT_NEAR(AngDiffDeg(again->pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.05);
  int reread = 0;
  ASSERT_EQ(std::sscanf(again->message.c_str(), "registered (%d columns re-read", &reread), 1) << again->message;
  EXPECT_GE(reread, k.width * 25 / 100);
  const cv::Mat blocks = faint_copy(cv::Vec3b(kSky[0] - 4, kSky[1] - 4, kSky[2] - 2));  // 6
  EXPECT_FALSE(RecheckWithGuidedSkyline(blocks, nulled, horizon, first, RegistrationOptions{}));
  // In a sky whose own rows step by 7 (JPEG's 8-row blocks at a low
  // quality) the range's 11.5 is no step: the re-read needs 2.5 times the
  // sky's steps.
  cv::Mat blocky = hazy.clone();
  for (int c = 0; c < k.width; ++c)
    for (int r = 0; r < k.height && r < truth_y[c] - 1; ++r)
      if ((r / 8) % 2) blocky.at<cv::Vec3b>(r, c) -= cv::Vec3b(4, 4, 4);
  EXPECT_FALSE(RecheckWithGuidedSkyline(blocky, nulled, horizon, first, RegistrationOptions{}));
}

TEST_F(GuidedSkylineTest, AUniformSkyOrAWrongPoseIsNotConfirmed) {
  const Registration first = Register(skyline, horizon, RegistrationOptions{});
  ASSERT_FALSE(first.registered) << first.message;
  // No snow: the sky really reaches down to the extracted boundary.
  cv::Mat plain = image.clone();
  for (int c = 0; c < k.width; ++c)
    for (int r = 0; r < static_cast<int>(skyline.y[c]) && r < k.height; ++r) plain.at<cv::Vec3b>(r, c) = kSky;
  const auto none = RecheckWithGuidedSkyline(plain, skyline, horizon, first, RegistrationOptions{});
  EXPECT_TRUE(!none || !none->registered);
  EXPECT_FALSE(RegisterImage(plain, skyline, horizon, RegistrationOptions{}).registered);
  // A pose 1 deg off: the re-read columns pull the fit back to the truth,
  // which is not the pose that was to be confirmed.
  Registration wrong = first;
  wrong.pose.azimuth_deg += 1.0;
  const auto moved = RecheckWithGuidedSkyline(image, skyline, horizon, wrong, RegistrationOptions{});
  ASSERT_TRUE(moved);
  EXPECT_FALSE(moved->registered);
  // The first look's answer leads, then why the second look did not change it.
  EXPECT_EQ(moved->message.rfind(wrong.message + "; a second look, ", 0), 0u) << moved->message;
  EXPECT_NE(moved->message.find("columns re-read near the DEM horizon: the re-read skyline moved the pose"),
            std::string::npos)
      << moved->message;
  // A registered first result is left alone.
  Registration done = first;
  done.registered = true;
  EXPECT_FALSE(RecheckWithGuidedSkyline(image, skyline, horizon, done, RegistrationOptions{}));
}

}  // namespace
}  // namespace horizonreg
