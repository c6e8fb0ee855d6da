// SPDX-License-Identifier: MIT
#include "track/track.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "render/render.h"
#include "testing/cone_ring.h"
#include "util/angles.h"

namespace horizonreg {
namespace {

TEST(TrackerOptions, DefaultsAreValid) { EXPECT_NO_THROW(TrackerOptions{}.Check()); }

// The cone ring rendered during a pan.
TEST(Tracker, FollowsARenderedPanAndFallsBackToCalibratedSensors) {
  const testing::ConeRing ring = testing::MakeConeRing();
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

}  // namespace
}  // namespace horizonreg
