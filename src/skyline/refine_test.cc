// SPDX-License-Identifier: MIT
#include "skyline/refine.h"

#include <gtest/gtest.h>

#include <cmath>

namespace horizonreg::skyline_detail {
namespace {

constexpr int kW = 200, kH = 120, kTop = 60, kBoundary = 70;  // the hazy band: rows kTop .. kBoundary - 1

// A blue sky down to row kTop, then `band(x, y)` down to kBoundary, then snow.
template <typename Band>
cv::Mat Scene(Band band) {
  cv::Mat img(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      img.at<cv::Vec3b>(y, x) = y < kTop ? cv::Vec3b(185, 150 + y / 12, 118 + y / 12)
                                : y < kBoundary ? band(x, y)
                                                : cv::Vec3b(238, 236, 234);
  return img;
}

int CountAt(const std::vector<double>& y, double row) {
  int n = 0;
  for (double v : y) n += std::abs(v - row) <= 1.0;
  return n;
}

TEST(RaiseToSkyEnd, AHazyRidgeTakenForSkyIsGivenBack) {
  // Rock and snow tinted by the air: a few delta E off the sky, textured.
  const cv::Mat img = Scene([](int x, int y) {
    const int n = (x * 37 + y * 91 + x * y * 7) % 21 - 10;
    return cv::Vec3b(cv::saturate_cast<uchar>(170 + n), cv::saturate_cast<uchar>(160 + n),
                     cv::saturate_cast<uchar>(150 + n));
  });
  std::vector<double> y(kW, kBoundary);
  RaiseToSkyEnd(img, std::vector<uint8_t>(kW, 0), y);
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.9 * kW);
}

TEST(RaiseToSkyEnd, ASmoothCloudOrABoundaryAtTheSkysEndStays) {
  // A cloud's smooth gradient (it changes from column to column, its
  // second difference does not): not terrain.
  const cv::Mat cloud = Scene([](int x, int y) {
    const double v = 200 + 50 * std::sin(x / 8.0) + 2 * (y - kTop);
    return cv::Vec3b::all(cv::saturate_cast<uchar>(v));
  });
  std::vector<double> y(kW, kBoundary);
  RaiseToSkyEnd(cloud, std::vector<uint8_t>(kW, 0), y);
  EXPECT_GE(CountAt(y, kBoundary), 0.95 * kW);

  // Sky straight down to the boundary.
  const cv::Mat clear = Scene([](int, int row) { return cv::Vec3b(185, 150 + row / 12, 118 + row / 12); });
  y.assign(kW, kBoundary);
  RaiseToSkyEnd(clear, std::vector<uint8_t>(kW, 0), y);
  EXPECT_EQ(CountAt(y, kBoundary), kW);
}

TEST(RaiseToSkyEnd, NullAndSkippedColumnsAreLeftAlone) {
  const cv::Mat img = Scene([](int x, int y) {
    const int n = (x * 37 + y * 91 + x * y * 7) % 21 - 10;
    return cv::Vec3b::all(cv::saturate_cast<uchar>(160 + n));
  });
  std::vector<double> y(kW, kBoundary);
  std::vector<uint8_t> skip(kW, 0);
  for (int x = 0; x < kW; x += 2) skip[x] = 1;
  y[1] = NAN;
  RaiseToSkyEnd(img, skip, y);
  EXPECT_TRUE(std::isnan(y[1]));
  for (int x = 0; x < kW; x += 2) EXPECT_EQ(y[x], kBoundary) << x;
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.45 * kW);  // the other odd columns
}

}  // namespace
}  // namespace horizonreg::skyline_detail
