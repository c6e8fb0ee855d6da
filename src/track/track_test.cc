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

// A ring of cones around the observer, rendered during a pan.
TEST(Tracker, FollowsARenderedPanAndFallsBackToCalibratedSensors) {
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
  const TerrainWindow w = testing::WindowOf(std::move(g));
  const GeodeticPoint eye = ResolveObserver(w, lat0, lon0, 1.7, std::nullopt);
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  ho.max_distance_m = 30'000.0;
  const HorizonProfile horizon = ComputeHorizon(w, eye, ho);
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

}  // namespace
}  // namespace horizonreg
