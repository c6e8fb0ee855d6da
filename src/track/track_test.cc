// SPDX-License-Identifier: MIT
#include "track/track.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "render/render.h"
#include "testing/synthetic_dem.h"
#include "util/angles.h"

namespace horizonreg {
namespace {

TEST(TrackerOptions, DefaultsAreValid) { EXPECT_NO_THROW(TrackerOptions{}.Check()); }

TEST(BandSkyline, FindsAStepInsideTheBandOnly) {
  cv::Mat img(100, 40, CV_8UC3, cv::Scalar(230, 200, 170));
  img.rowRange(60, 100).setTo(cv::Scalar(60, 110, 70));  // terrain from row 60
  img.rowRange(20, 22).setTo(cv::Scalar(0, 0, 0));       // a dark line far above
  std::vector<double> predicted(40, 57.0);
  predicted[5] = NAN;
  const Skyline s = BandSkyline(img, predicted, 8.0, 30.0);
  EXPECT_TRUE(std::isnan(s.y[5]));
  for (int c : {0, 20, 39}) EXPECT_NEAR(s.y[c], 60.0, 0.5) << c;
  const Skyline none = BandSkyline(cv::Mat(100, 40, CV_8UC3, cv::Scalar(128, 128, 128)), predicted, 8.0, 30.0);
  EXPECT_EQ(none.VisibleCount(), 0);
}

// A ring of nine cones 5-8 km around an observer at (46, 8), and its horizon
// (0.1 deg bins, 30 km).
struct ConeRing {
  TerrainWindow window;
  GeodeticPoint eye;
  HorizonProfile horizon;
};
ConeRing MakeConeRing() {
  std::vector<std::function<double(double, double)>> cones;
  const double lat0 = 46.0, lon0 = 8.0;
  for (int i = 0; i < 9; ++i) {
    const double a = DegToRad(i * 37.0 + 5.0), d = 0.06 + 0.015 * (i % 3);
    cones.push_back(testing::ConeHeight(lat0 + d * std::cos(a), lon0 + d * std::sin(a) / std::cos(DegToRad(lat0)),
                                        500.0, 700.0 + 180.0 * (i % 4), 2500.0 + 400.0 * (i % 2)));
  }
  DemGrid g = testing::SynthesizeDem(46.15, 7.8, 1.0 / 1200, 500, 361, [&](double lat, double lon) {
    double h = 500.0;
    for (const auto& f : cones) h = std::max(h, f(lat, lon));
    return h;
  });
  ConeRing ring;
  ring.window = testing::WindowOf(std::move(g));
  ring.eye = ResolveObserver(ring.window, lat0, lon0, 1.7, std::nullopt);
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  ho.max_distance_m = 30'000.0;
  ring.horizon = ComputeHorizon(ring.window, ring.eye, ho);
  return ring;
}

// The cone ring rendered during a pan.
TEST(Tracker, FollowsARenderedPanAndFallsBackToCalibratedSensors) {
  const ConeRing ring = MakeConeRing();
  const TerrainWindow& w = ring.window;
  const GeodeticPoint& eye = ring.eye;
  const HorizonProfile& horizon = ring.horizon;
  RenderOptions ro;
  ro.max_distance_m = 30'000.0;
  const auto k = CameraIntrinsics::FromHfov(480, 320, 50.0);
  Tracker tracker(horizon, k.width, k.height, {});
  int vision = 0, tracked = 0, sensors = 0;
  for (int f = 0; f < 14; ++f) {
    const CameraPose truth{WrapAzimuthDeg(20.0 + 1.5 * f), 2.0 - 0.05 * f, 0.5};
    SensorReading raw;
    raw.compass_deg = WrapAzimuthDeg(truth.azimuth_deg - 6.0);
    raw.pitch_deg = truth.pitch_deg + 1.0;
    raw.roll_deg = truth.roll_deg;
    cv::Mat frame = RenderView(w, eye, truth, k, ro);
    if (f >= 11) frame.setTo(cv::Scalar(200, 200, 200));  // "fog": nothing to see
    const FramePose p = tracker.Process(frame, f, raw, f * 0.1);
    ASSERT_NE(p.source, PoseSource::kNone) << f;
    const double tol = p.source == PoseSource::kSensors ? 0.5 : 0.1;
    EXPECT_NEAR(AngDiffDeg(p.pose.azimuth_deg, truth.azimuth_deg), 0.0, tol) << f << " " << PoseSourceName(p.source);
    EXPECT_NEAR(p.pose.pitch_deg, truth.pitch_deg, tol) << f << " " << PoseSourceName(p.source);
    vision += p.source == PoseSource::kVision;
    tracked += p.source == PoseSource::kTracked;
    sensors += p.source == PoseSource::kSensors;
  }
  EXPECT_GE(vision, 1);
  EXPECT_GE(tracked, 8);  // the cheap path carries the pan
  EXPECT_EQ(sensors, 3);  // the fog frames
  ASSERT_TRUE(tracker.calibration());
  EXPECT_NEAR(tracker.calibration()->compass_offset_deg, 6.0, 0.1);
}

// The cone ring as a flat-coloured photo whose skyline
// extraction missed a snow field: in the left 30% of the columns the extracted
// boundary lies 25 px low, at the snow's lower edge.
class GuidedSkylineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    horizon = MakeConeRing().horizon;
    const std::vector<double> truth_y = PredictedSkyline(horizon, truth, k);
    image = cv::Mat(k.height, k.width, CV_8UC3, cv::Scalar(230, 200, 170));  // sky
    skyline.width = k.width;
    skyline.height = k.height;
    skyline.y = truth_y;
    skyline.confidence.assign(k.width, 1.0);
    for (int c = 0; c < k.width; ++c) {
      const bool snow = c < k.width * 30 / 100;
      const int top = static_cast<int>(std::lround(truth_y[c]));
      for (int r = std::max(0, top); r < k.height; ++r)
        image.at<cv::Vec3b>(r, c) = r < top + 25 && snow ? cv::Vec3b(235, 235, 235) : cv::Vec3b(60, 110, 70);
      if (snow) skyline.y[c] = top + 25.0;
    }
  }
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(480, 320, 50.0);
  const CameraPose truth{25.0, 2.0, 0.5};
  HorizonProfile horizon;
  cv::Mat image;
  Skyline skyline;
};

TEST_F(GuidedSkylineTest, ANearMissBecomesARegistrationAtTheTruePose) {
  const Registration first = Register(skyline, horizon, RegistrationOptions{});
  ASSERT_FALSE(first.registered) << first.message;  // 70% fit, and the misread columns leave it ambiguous
  ASSERT_GE(first.inlier_fraction, RegistrationOptions{}.min_inlier_fraction - 0.2) << first.message;
  const auto again = RecheckWithGuidedSkyline(image, skyline, horizon, first, RegistrationOptions{});
  ASSERT_TRUE(again);
  ASSERT_TRUE(again->registered) << again->message;
  EXPECT_NEAR(AngDiffDeg(again->pose.azimuth_deg, truth.azimuth_deg), 0.0, 0.05);
  EXPECT_NEAR(again->pose.pitch_deg, truth.pitch_deg, 0.05);
  EXPECT_GE(again->inlier_fraction, 0.95);
  EXPECT_TRUE(RegisterImage(image, skyline, horizon, RegistrationOptions{}).registered);
}

TEST_F(GuidedSkylineTest, AUniformSkyOrAWrongPoseIsNotConfirmed) {
  const Registration first = Register(skyline, horizon, RegistrationOptions{});
  ASSERT_FALSE(first.registered) << first.message;
  // No snow: the sky really reaches down to the extracted boundary.
  cv::Mat plain = image.clone();
  for (int c = 0; c < k.width; ++c)
    for (int r = 0; r < static_cast<int>(skyline.y[c]) && r < k.height; ++r)
      plain.at<cv::Vec3b>(r, c) = cv::Vec3b(230, 200, 170);
  const auto none = RecheckWithGuidedSkyline(plain, skyline, horizon, first, RegistrationOptions{});
  EXPECT_TRUE(!none || !none->registered);
  EXPECT_FALSE(RegisterImage(plain, skyline, horizon, RegistrationOptions{}).registered);
  // A pose 1 deg off: the re-read columns pull the fit back to the truth,
  // which is not the pose that was to be confirmed.
  Registration wrong = first;
  wrong.pose.azimuth_deg += 1.0;
  const auto moved = RecheckWithGuidedSkyline(image, skyline, horizon, wrong, RegistrationOptions{});
  EXPECT_TRUE(!moved || !moved->registered);
  // Hidden (null) columns stay null; a registered first result is left alone.
  Registration done = first;
  done.registered = true;
  EXPECT_FALSE(RecheckWithGuidedSkyline(image, skyline, horizon, done, RegistrationOptions{}));
}

}  // namespace
}  // namespace horizonreg
