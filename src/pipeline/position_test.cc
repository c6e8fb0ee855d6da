// SPDX-License-Identifier: MIT
#include "pipeline/position.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <opencv2/core.hpp>

#include "match/position_fit.h"
#include "match/predicted.h"
#include "pipeline/register_photo.h"
#include "pipeline/report.h"
#include "pipeline/site.h"
#include "render/render.h"
#include "testing/cone_ring.h"
#include "testing/near_far.h"
#include "testing/synthetic_dem.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

using testing::kNearFarLat;
using testing::kNearFarLon;
using testing::NearFarWindow;
constexpr double kLat = kNearFarLat, kLon = kNearFarLon;

SiteOptions Options(double alt_m) {
  SiteOptions o;
  o.alt_m = alt_m;
  o.max_distance_m = 12'000.0;
  return o;
}

// (lat, lon) `east_m`, `north_m` from the observer.
std::pair<double, double> Moved(double east_m, double north_m) {
  const LocalFrame f({kLat, kLon, 0.0});
  const GeodeticPoint p = f.GeodeticFromEnu({east_m, north_m, 0.0});
  return {p.lat_deg, p.lon_deg};
}

TEST(PositionOptions, DefaultsAreValidAndBySource) {
  PositionOptions{}.Check();
  EXPECT_EQ(DefaultPositionOptions("arguments", false, std::nullopt).horizontal_sigma_m, 15.0);
  EXPECT_EQ(DefaultPositionOptions("exif", true, std::nullopt).horizontal_sigma_m, 10.0);
  EXPECT_EQ(DefaultPositionOptions("exif", true, std::nullopt).vertical_sigma_m, 20.0);
  EXPECT_EQ(DefaultPositionOptions("arguments", false, 40.0).horizontal_sigma_m, 40.0);
  PositionOptions bad;
  bad.vertical_sigma_m = 0.0;
  EXPECT_THROW(bad.Check(), InvalidArgument);
}

TEST(HorizonPositionGradient, PredictsTheHorizonOfASmallMove) {
  const TerrainWindow w = NearFarWindow();
  const GeodeticPoint eye = ResolveObserver(w, kLat, kLon, 1.7, std::nullopt);
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  ho.max_distance_m = 12'000.0;
  const HorizonProfile h0 = ComputeHorizon(w, eye, ho);
  const Eigen::Vector3d move(4.0, -3.0, 2.0);
  const HorizonProfile h1 = ComputeHorizon(w, LocalFrame(eye).GeodeticFromEnu(move), ho);
  const std::vector<Eigen::Vector3d> g = HorizonPositionGradient(h0);
  std::vector<double> err, change;
  for (int i = 0; i < h0.size(); ++i) {  // the near hills' bins
    if (!(h0.distance_m[i] < 2000.0) || !(h1.distance_m[i] < 2000.0)) continue;
    const double predicted = RadToDeg(g[i].dot(move));
    change.push_back(std::abs(h1.elevation_deg[i] - h0.elevation_deg[i]));
    err.push_back(std::abs(h1.elevation_deg[i] - h0.elevation_deg[i] - predicted));
  }
  ASSERT_GT(err.size(), 100u);
  std::sort(err.begin(), err.end());
  std::sort(change.begin(), change.end());
  EXPECT_GT(change[change.size() / 2], 0.05);                        // the move matters there
  EXPECT_LT(err[err.size() / 2], 0.25 * change[change.size() / 2]);  // and is predicted to first order
}

class PositionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    window = NearFarWindow();
    eye = ResolveObserver(window, kLat, kLon, 1.7, std::nullopt);
  }
  // The exact skyline of the truth pose seen from the true eye.
  Skyline TrueSkyline(const TerrainWindow& w, const GeodeticPoint& at) const {
    return testing::ExactSkyline(w, at, truth, k, 12'000.0);
  }
  // The true skyline registered at a position 30 m off and 20 m too high
  // (no distortion fitted), with the priors of given coordinates.
  struct OffsetStart {
    Skyline sky;
    std::unique_ptr<Site> site;
    PositionOptions po;
    RegistrationOptions ro;
    Registration first;
  };
  OffsetStart RegisterOffset() const {
    OffsetStart o;
    o.sky = TrueSkyline(window, eye);
    const auto [lat, lon] = Moved(21.0, -21.0);
    o.site = std::make_unique<Site>(TerrainWindow(window), lat, lon, Options(eye.height_m + 20.0));
    o.po = DefaultPositionOptions("arguments", false, std::nullopt);
    o.ro.dem_error.position_sigma_m = o.po.horizontal_sigma_m;
    o.ro.dem_error.height_sigma_m = o.po.vertical_sigma_m;
    o.ro.estimate_distortion = false;
    o.first = Register(o.sky, o.site->horizon(), o.ro);
    return o;
  }
  TerrainWindow window;
  GeodeticPoint eye;
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(640, 400, 60.0);
  const CameraPose truth{45.0, 1.0, 0.5};
};

TEST_F(PositionTest, RecoversAnOffsetPositionWhereNearHillsShowIt) {
  const auto [sky, site, po, ro, first] = RegisterOffset();
  ASSERT_GT(first.focal_px, 0.0) << first.message;
  const PositionEstimate e = RefinePosition(*site, sky, first, ro, po);
  ASSERT_TRUE(e.observable) << e.message;
  const Eigen::Vector3d at = LocalFrame(eye).EnuFromGeodetic(e.observer);
  EXPECT_LT(at.head<2>().norm(), 5.0) << e.message << " at " << at.transpose();
  EXPECT_LT(std::abs(at.z()), 3.0) << e.message << " at " << at.transpose();
  EXPECT_LT(e.sigma_enu_m.maxCoeff(), 0.5 * po.vertical_sigma_m);
  EXPECT_GE(e.horizons, 1);
  // Registered again at the estimate, the orientation is the truth's.
  RegistrationOptions at_estimate = ro;
  at_estimate.dem_error.position_sigma_m = at_estimate.dem_error.height_sigma_m = 2.0;
  const Registration r = Register(sky, e.horizon, at_estimate);
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.1);
  EXPECT_NEAR(r.pose.pitch_deg, truth.pitch_deg, 0.1);
}

// A registration at a position tens of metres off can fit k1 to the
// parallax the position makes (cascades_02: +0.14, with the focal length 3%
// short). The refinement fits k1 with the position instead of holding it:
// here the same start as above with a pincushion k1 of +0.12 and the focal
// length 3% short, which held would keep the fit from the true position.
TEST_F(PositionTest, FitsK1AgainWhenTheRegistrationFittedIt) {
  auto [sky, site, po, ro, first] = RegisterOffset();
  ASSERT_GT(first.focal_px, 0.0) << first.message;
  first.focal_px *= 0.97;
  first.intrinsics.distortion = LensDistortion::Radial(0.12);
  first.distortion_estimated = true;
  const PositionEstimate e = RefinePosition(*site, sky, first, ro, po);
  ASSERT_TRUE(e.observable_axis[2]) << e.message;
  const Eigen::Vector3d at = LocalFrame(eye).EnuFromGeodetic(e.observer);
  EXPECT_LT(std::abs(at.z()), 3.0) << e.message << " at " << at.transpose();
  EXPECT_LT(at.head<2>().norm(), 10.0) << e.message << " at " << at.transpose();
  // The joint fit itself: from k1 +0.12 at the true position, k1 goes back
  // towards the pinhole's 0 when free and stays when held.
  const Site at_truth(TerrainWindow(window), kLat, kLon, Options(eye.height_m));
  const PoseAndPositionFit freed =
      FitPoseAndPosition(sky, at_truth.horizon(), truth, 0.97 * k.focal_px, 0.12, true, false, Eigen::Vector3d::Zero(),
                         Eigen::Vector3d(15.0, 15.0, 10.0), ro, 1.0, 12, Eigen::Vector3d::Zero());
  const PoseAndPositionFit held =
      FitPoseAndPosition(sky, at_truth.horizon(), truth, 0.97 * k.focal_px, 0.12, false, false, Eigen::Vector3d::Zero(),
                         Eigen::Vector3d(15.0, 15.0, 10.0), ro, 1.0, 12, Eigen::Vector3d::Zero());
  EXPECT_NEAR(freed.k1, 0.0, 0.02);
  EXPECT_NEAR(freed.focal_px, k.focal_px, 0.01 * k.focal_px);
  EXPECT_EQ(held.k1, 0.12);
  EXPECT_LT(freed.cost, held.cost);
}

TEST_F(PositionTest, KeepsThePriorWhenTheHorizonIsAllFarAway) {
  testing::ConeRing ring = testing::MakeConeRing();  // cones 5-8 km away, nothing near
  const Skyline sky = TrueSkyline(ring.window, ring.eye);
  const auto [lat, lon] = Moved(10.0, 10.0);
  const Site site(TerrainWindow(ring.window), lat, lon, Options(ring.eye.height_m + 5.0));
  RegistrationOptions ro;
  ro.estimate_distortion = false;
  ro.dem_error.position_sigma_m = 15.0;
  ro.dem_error.height_sigma_m = 10.0;
  const Registration first = Register(sky, site.horizon(), ro);
  ASSERT_TRUE(first.registered) << first.message;
  PositionOptions po;
  po.horizontal_sigma_m = 15.0;
  const PositionEstimate e = RefinePosition(site, sky, first, ro, po);
  EXPECT_FALSE(e.observable) << e.message;
  if (!e.observable_axis[0] && !e.observable_axis[1] && !e.observable_axis[2]) {
    EXPECT_EQ(e.observer.lat_deg, site.observer().lat_deg);
    EXPECT_EQ(e.sigma_enu_m, e.prior_sigma_enu_m);
    EXPECT_NE(e.message.find("not observable"), std::string::npos) << e.message;
  }
}

TEST_F(PositionTest, RegisterPhotoReportsTheRefinedPosition) {
  const auto [lat, lon] = Moved(-15.0, 26.0);
  ThreadPool pool(2);
  const Site site(TerrainWindow(window), lat, lon, Options(eye.height_m - 20.0), &pool);  // below the ground there
  RenderOptions rop;
  rop.max_distance_m = 12'000.0;
  const cv::Mat photo = RenderView(window, eye, truth, k, rop);
  PhotoOptions po;
  po.pinhole = true;
  // The exact skyline: the extractor is not what is tested here (on this
  // flat-shaded synthetic view it finds a fifth of the columns).
  po.skyline = TrueSkyline(window, eye);
  po.refine_position = DefaultPositionOptions("arguments", false, std::nullopt);
  const PhotoRegistration r = RegisterPhoto(site, photo, po, &pool);
  ASSERT_TRUE(r.position);
  ASSERT_TRUE(r.registration.registered) << r.registration.message << "; " << r.position->message;
  const Eigen::Vector3d at = LocalFrame(eye).EnuFromGeodetic(r.position->observer);
  EXPECT_LT(at.head<2>().norm(), 8.0) << r.position->message;
  EXPECT_LT(std::abs(at.z()), 5.0) << r.position->message;
  EXPECT_NEAR(AngDiffDeg(r.registration.pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.3);
  EXPECT_NEAR(r.registration.pose.pitch_deg, truth.pitch_deg, 0.3);
  const nlohmann::json j = RegistrationReport(site, r, "arguments", 1.0);
  ASSERT_TRUE(j.contains("position"));
  EXPECT_NEAR(j["position"]["lat"].get<double>(), r.position->observer.lat_deg, 1e-7);
  EXPECT_TRUE(j["position"]["observable"].is_boolean());
  EXPECT_NEAR(j["observer"]["lat"].get<double>(), lat, 1e-6);  // the given position stays
  EXPECT_TRUE(j["timing_ms"].contains("position"));
}

}  // namespace
}  // namespace horizonreg
