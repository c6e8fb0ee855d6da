// SPDX-License-Identifier: MIT
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "skyline/skyline.h"
#include "testing/flat_skyline.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

constexpr int kW = 400, kH = 220;

// A pale sky lightening towards the horizon over a hazy far ridge a few
// delta E off it (top at far[x]), over a bright snowy near range (top at
// near_top, the clear edge an extractor takes); JPEG-like noise of 1 level.
// Without the ridge the sky reaches down to the near range; a cloud is a
// white band at rows 60-63 with sky under it.
cv::Mat HazyRidge(std::vector<double>& far, int near_top, bool ridge = true, bool cloud = false) {
  cv::Mat img(kH, kW, CV_8UC3);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> noise(-1, 1);
  far.resize(kW);
  for (int x = 0; x < kW; ++x) far[x] = ridge ? 80.0 + 4.0 * std::sin(x / 23.0) : INFINITY;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      cv::Vec3i c(200 + y / 8, 170 + y / 6, 140 + y / 6);  // BGR sky, lighter and greyer lower down
      if (y >= near_top) {
        c = cv::Vec3i(235, 235, 232);  // snow
      } else if (y + 0.5 >= far[x]) {
        c += cv::Vec3i(-14, -10, -4);  // the hazy ridge: a few delta E darker and less blue
      } else if (cloud && y >= 60 && y < 64) {
        c = cv::Vec3i(245, 245, 245);  // a thin cloud with sky below it
      }
      for (int k = 0; k < 3; ++k) c[k] = std::clamp(c[k] + noise(rng), 0, 255);
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(c[0], c[1], c[2]);
    }
  return img;
}

// The skyline an extractor gives when it stops at row y in every column.
Skyline Extracted(double y) { return testing::FlatSkyline(kW, kH, y); }

// The extractor stopped at the near range's clear edge, 14-22 rows below the
// hazy ridge's top; the DEM horizon lies 2 rows below that top (flattened).
TEST(GuideSkyline, FindsTheHazyRidgeAboveAClearerEdge) {
  std::vector<double> far;
  const cv::Mat img = HazyRidge(far, 102);
  const Skyline s = Extracted(102.0);
  std::vector<double> pred(kW), above(kW, 12.0), below(kW, 3.0);
  for (int x = 0; x < kW; ++x) pred[x] = far[x] + 2.0;
  const Skyline g = GuideSkyline(img, s, pred, above, below);
  int near = 0;
  for (int x = 0; x < kW; ++x) near += std::abs(g.y[x] - std::ceil(far[x] - 0.5)) <= 1.0;
  EXPECT_GE(near, 0.95 * kW);
  EXPECT_TRUE(g.y_alt.empty());
}

// Columns whose boundary lies inside the window, or whose prediction is
// missing, keep the extracted value; so does a window that is NaN.
TEST(GuideSkyline, KeepsBoundariesInsideTheWindowAndUnpredictedColumns) {
  std::vector<double> far;
  const cv::Mat img = HazyRidge(far, 102);
  const Skyline s = Extracted(102.0);
  std::vector<double> pred(kW, 100.0), above(kW, 12.0), below(kW, 3.0);
  for (int x = 0; x < 50; ++x) pred[x] = NAN;
  for (int x = 50; x < 100; ++x) above[x] = NAN;
  const Skyline g = GuideSkyline(img, s, pred, above, below);
  for (int x = 0; x < kW; ++x) EXPECT_EQ(g.y[x], 102.0) << x;
  // A null column (a tree, fog) stays null, though a ridge lies in its window.
  Skyline hidden = s;
  for (int x = 0; x < kW; ++x) pred[x] = far[x] + 2.0, above[x] = 12.0;
  for (int x = 200; x < 220; ++x) hidden.y[x] = NAN;
  const Skyline h = GuideSkyline(img, hidden, pred, above, below);
  for (int x = 200; x < 220; ++x) EXPECT_TRUE(std::isnan(h.y[x])) << x;
  EXPECT_LT(h.y[100], 95.0);  // ... where the others are read again
}

// A thin cloud with blue sky under it is no ridge: the departure must hold
// down to the extracted boundary.
TEST(GuideSkyline, ACloudOverSkyIsNotTerrain) {
  std::vector<double> far;
  const cv::Mat clear = HazyRidge(far, 102, /*ridge=*/false, /*cloud=*/true);
  const Skyline s = Extracted(102.0);
  std::vector<double> pred(kW, 75.0), above(kW, 20.0), below(kW, 3.0);
  const Skyline g = GuideSkyline(clear, s, pred, above, below);
  for (int x = 0; x < kW; ++x) EXPECT_EQ(g.y[x], 102.0) << x;
}

TEST(GuideSkyline, RejectsMismatchedSizes) {
  std::vector<double> far;
  const cv::Mat img = HazyRidge(far, 102);
  const Skyline s = Extracted(102.0);
  std::vector<double> ok(kW, 10.0), short_(kW - 1, 10.0);
  EXPECT_THROW(GuideSkyline(img, s, short_, ok, ok), InvalidArgument);
  EXPECT_THROW(GuideSkyline(img, s, ok, ok, short_), InvalidArgument);
  EXPECT_THROW(GuideSkyline(img(cv::Rect(0, 0, kW - 1, kH)).clone(), s, ok, ok, ok), InvalidArgument);
}

}  // namespace
}  // namespace horizonreg
