// SPDX-License-Identifier: MIT
#include "skyline/band.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

namespace horizonreg {
namespace {

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

TEST(AsBgr, GreyBecomesThreeEqualChannels) {
  const cv::Mat grey(4, 5, CV_8UC1, cv::Scalar(77));
  const cv::Mat bgr = AsBgr(grey);
  ASSERT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(bgr.at<cv::Vec3b>(2, 3), cv::Vec3b(77, 77, 77));
}

}  // namespace
}  // namespace horizonreg
