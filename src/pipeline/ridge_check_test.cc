// SPDX-License-Identifier: MIT
#include "pipeline/ridge_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

constexpr double kStepDeg = 0.25;
constexpr double kHorizonDeg = 3.0;

// A far horizon at 3 deg all round, and an inner ridge 3 km away between
// azimuths 50 and 130 deg, undulating about 1 deg.
double RidgeDeg(double az_deg) { return 1.0 + 0.5 * std::sin(DegToRad(4.0 * az_deg)); }

HorizonProfile FlatHorizon() {
  HorizonProfile h;
  h.azimuth_step_deg = kStepDeg;
  const int n = static_cast<int>(std::lround(360.0 / kStepDeg));
  h.elevation_deg.assign(n, kHorizonDeg);
  h.distance_m.assign(n, 20000.0);
  h.lat_deg.assign(n, 0.0), h.lon_deg.assign(n, 0.0), h.height_m.assign(n, 0.0);
  return h;
}

std::vector<std::vector<Ridge>> InnerRidges(const HorizonProfile& h) {
  std::vector<std::vector<Ridge>> r(h.size());
  for (int i = 0; i < h.size(); ++i)
    if (const double az = h.AzimuthDeg(i); az >= 50.0 && az <= 130.0) r[i].push_back({RidgeDeg(az), 3000.0});
  return r;
}

// The view rendered at `pose`: sky 200, the far terrain 140, the near ridge's slope 70.
cv::Mat Render(const CameraPose& pose, const CameraIntrinsics& k) {
  cv::Mat img(k.height, k.width, CV_8UC3);
  const Eigen::Matrix3d m = CamFromEnu(pose);
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector3d d = UnprojectToEnu(m, k, Eigen::Vector2d(x + 0.5, y + 0.5));
      const double az = WrapAzimuthDeg(RadToDeg(std::atan2(d.x(), d.y())));
      const double el = RadToDeg(std::asin(d.z()));
      const uchar v = el > kHorizonDeg ? 200 : (az >= 50.0 && az <= 130.0 && el < RidgeDeg(az)) ? 70 : 140;
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(v, v, v);
    }
  return img;
}

// The view at the true pose, its horizon and ridges.
class RidgeCheckTest : public ::testing::Test {
 protected:
  const HorizonProfile h = FlatHorizon();
  const std::vector<std::vector<Ridge>> ridges = InnerRidges(h);
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(800, 500, 40.0);
  const CameraPose truth{90.0, 0.0, 0.0};
  const PhotoEdges edges = ComputePhotoEdges(Render(truth, k));
};

TEST_F(RidgeCheckTest, TheTruePoseFindsItsRidgesOnEdgesAndAnotherDoesNot) {
  const RidgeSupport at_truth = MeasureRidgeSupport(edges, h, ridges, truth, k);
  EXPECT_GT(at_truth.points, 100);
  EXPECT_GT(at_truth.Share(), 0.9);
  // Pitched 1.5 deg (the ridge 35 px off its edge) or turned 10 deg (its
  // undulation out of phase): few points on an edge.
  EXPECT_LT(MeasureRidgeSupport(edges, h, ridges, {90.0, 1.5, 0.0}, k).Share(), 0.1);
  EXPECT_LT(MeasureRidgeSupport(edges, h, ridges, {100.0, 0.0, 0.0}, k).Share(), 0.5);
  // Where the DEM has no inner ridge, or the photo no edge, nothing counts.
  EXPECT_EQ(MeasureRidgeSupport(edges, h, ridges, {250.0, 0.0, 0.0}, k).points, 0);
  const PhotoEdges flat = ComputePhotoEdges(cv::Mat(500, 800, CV_8UC3, cv::Scalar(128, 128, 128)));
  EXPECT_EQ(MeasureRidgeSupport(flat, h, ridges, truth, k).supported, 0);
  EXPECT_THROW(MeasureRidgeSupport(edges, h, ridges, truth, CameraIntrinsics::FromHfov(640, 480, 40.0)),
               InvalidArgument);
  EXPECT_THROW(ComputePhotoEdges(cv::Mat()), InvalidArgument);
}

TEST_F(RidgeCheckTest, RulesOutARivalTheRidgesContradictOnly) {
  Registration reg;
  reg.pose = truth;
  reg.focal_px = k.focal_px;
  reg.intrinsics = k;
  reg.candidates = {{truth, k.focal_px, 1.0, 0.9},
                    {{90.0, 1.5, 0.0}, k.focal_px, 1.2, 0.7},    // a rival the ridges contradict
                    {{250.0, 0.0, 0.0}, k.focal_px, 1.1, 0.7},   // a rival with no ridge to read
                    {{110.0, 0.5, 0.0}, k.focal_px, 2.0, 0.3}};  // no threat: ratio 2 > 1.4
  const RidgeCheck rc = CheckRidges(edges, h, ridges, reg, RegistrationOptions{});
  EXPECT_GT(rc.best.Share(), 0.9);
  ASSERT_EQ(rc.rivals.size(), 2u);
  EXPECT_TRUE(rc.rivals[0].ruled_out);
  EXPECT_FALSE(rc.rivals[1].ruled_out);
  ASSERT_EQ(rc.RuledOut().size(), 1u);
  EXPECT_DOUBLE_EQ(rc.RuledOut()[0].pitch_deg, 1.5);
  // A photo whose edges do not show the best pose's ridges rules out nothing.
  const PhotoEdges flat = ComputePhotoEdges(cv::Mat(500, 800, CV_8UC3, cv::Scalar(128, 128, 128)));
  EXPECT_TRUE(CheckRidges(flat, h, ridges, reg, RegistrationOptions{}).RuledOut().empty());
}

RidgeSupport Support(int points, double share) { return {points, static_cast<int>(std::lround(share * points))}; }

TEST(RidgesRuleOut, AClearLeadOrAFarWeakerRival) {
  // The first rule: best at least 0.45 and 1.4 times the rival's.
  EXPECT_TRUE(RidgesRuleOut(Support(400, 0.60), Support(200, 0.40)));
  EXPECT_FALSE(RidgesRuleOut(Support(400, 0.60), Support(200, 0.46)));
  EXPECT_FALSE(
      RidgesRuleOut(Support(400, 0.44), Support(200, 0.20)));  // best too weak for it, rival too strong for the second
  // The second: best at least 0.35 and 3 times the rival's.
  EXPECT_TRUE(RidgesRuleOut(Support(380, 0.426), Support(216, 0.093)));
  EXPECT_FALSE(RidgesRuleOut(Support(380, 0.426), Support(216, 0.20)));
  EXPECT_FALSE(
      RidgesRuleOut(Support(380, 0.30), Support(216, 0.05)));  // below 0.35: the share any line gets on texture
  // Too few points on either side: no ruling.
  EXPECT_FALSE(RidgesRuleOut(Support(kRidgeMinPoints - 1, 0.9), Support(200, 0.0)));
  EXPECT_FALSE(RidgesRuleOut(Support(400, 0.9), Support(kRidgeMinPoints - 1, 0.0)));
  EXPECT_TRUE(RidgesRuleOut(Support(kRidgeMinPoints, 0.9), Support(kRidgeMinPoints, 0.0)));
}

}  // namespace
}  // namespace horizonreg
