// SPDX-License-Identifier: MIT
#include "camera/camera.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <random>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(CameraIntrinsics, FromHfovGivesDesignFocal) {
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(1024, 683, 30.0);
  EXPECT_NEAR(k.focal_px, 1910.8100134752654, 1e-9);  // (W / 2) / tan(hfov / 2)
  EXPECT_DOUBLE_EQ(k.cx_px, 512.0);
  EXPECT_DOUBLE_EQ(k.cy_px, 341.5);
  EXPECT_NEAR(k.HfovDeg(), 30.0, 1e-12);
  EXPECT_NO_THROW(k.Check());
  CameraIntrinsics bad = k;
  bad.focal_px = -1;
  EXPECT_THROW(bad.Check(), InvalidArgument);
}

TEST(ProjectAzEl, OpticalAxisLandsOnThePrincipalPoint) {
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(1000, 600, 50.0);
  const auto p = ProjectAzEl(CamFromEnu({123.0, 4.0, 7.0}), k, 123.0, 4.0);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->x(), 500.0, 1e-9);
  EXPECT_NEAR(p->y(), 300.0, 1e-9);
}

TEST(ProjectAzEl, RightIsClockwiseAndUpIsUp) {
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(1000, 600, 50.0);
  const auto m = CamFromEnu({90.0, 0.0, 0.0});
  const auto right = ProjectAzEl(m, k, 100.0, 0.0), up = ProjectAzEl(m, k, 90.0, 5.0);
  EXPECT_GT(right->x(), 500.0);
  EXPECT_NEAR(right->y(), 300.0, 1e-9);
  EXPECT_LT(up->y(), 300.0);
  // The half field of view lands on the image edge.
  EXPECT_NEAR(ProjectAzEl(m, k, 115.0, 0.0)->x(), 1000.0, 1e-9);
  EXPECT_FALSE(ProjectAzEl(m, k, 270.0, 0.0).has_value());  // behind
}

TEST(ProjectAzEl, PositiveRollRotatesTheSceneAnticlockwise) {
  // Right side down: the level horizon appears higher on the right.
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(1000, 600, 50.0);
  const auto m = CamFromEnu({0.0, 0.0, 5.0});
  const auto left = ProjectAzEl(m, k, -10.0, 0.0), right = ProjectAzEl(m, k, 10.0, 0.0);
  EXPECT_LT(right->y(), left->y());
  EXPECT_NEAR(std::atan2(left->y() - right->y(), right->x() - left->x()), DegToRad(5.0), 1e-9);
}

TEST(ProjectEnu, ProjectUnprojectRoundTrips) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> az(0, 360), pitch(-80, 80), roll(-30, 30), px(0, 1024), py(0, 683);
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(1024, 683, 60.0);
  for (int i = 0; i < 200; ++i) {
    const auto m = CamFromEnu({az(rng), pitch(rng), roll(rng)});
    const Eigen::Vector2d pixel(px(rng), py(rng));
    const auto back = ProjectEnu(m, k, UnprojectToEnu(m, k, pixel));
    ASSERT_TRUE(back);
    EXPECT_NEAR((*back - pixel).norm(), 0.0, 1e-8);
  }
}

TEST(CamFromEnu, IsARotationEvenLookingStraightUp) {
  for (double pitch : {-90.0, -45.0, 0.0, 89.999, 90.0}) {
    const Eigen::Matrix3d m = CamFromEnu({33.0, pitch, 12.0});
    EXPECT_NEAR((m * m.transpose() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
    EXPECT_NEAR(m.determinant(), 1.0, 1e-12);
  }
}

}  // namespace
}  // namespace horizonreg

namespace horizonreg {
namespace {

TEST(PoseFromCamFromEnu, RoundTripsCamFromEnu) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> az(0.0, 360.0), pitch(-89.0, 89.0), roll(-179.0, 179.0);
  for (int i = 0; i < 500; ++i) {
    const CameraPose p{az(rng), pitch(rng), roll(rng)};
    const CameraPose q = PoseFromCamFromEnu(CamFromEnu(p));
    EXPECT_NEAR(AngDiffDeg(q.azimuth_deg, p.azimuth_deg), 0.0, 1e-9);
    EXPECT_NEAR(q.pitch_deg, p.pitch_deg, 1e-9);
    EXPECT_NEAR(q.roll_deg, p.roll_deg, 1e-9);
  }
}

TEST(PoseFromCamFromEnu, GimbalLockFoldsRollIntoAzimuth) {
  for (double pitch : {-90.0, 90.0}) {
    const Eigen::Matrix3d m = CamFromEnu({40.0, pitch, 15.0});
    const CameraPose q = PoseFromCamFromEnu(m);
    EXPECT_NEAR(q.roll_deg, 0.0, 1e-12);
    EXPECT_NEAR((CamFromEnu(q) - m).norm(), 0.0, 1e-9) << "pitch " << pitch;
  }
}

}  // namespace
}  // namespace horizonreg
