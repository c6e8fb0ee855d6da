// SPDX-License-Identifier: MIT
#include "skyline/sky_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace horizonreg::skyline_detail {
namespace {

// A grey sky that lightens downwards as a cubic in y (L = 50 + 40 y^3) on
// planes of `cols` columns x `rows` rows (transposed layout).
LabPlanes CubicSky(int cols, int rows) {
  LabPlanes lab;
  lab.Create(cols, rows);
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) {
      const double y = static_cast<double>(r) / (rows - 1);
      lab.l.at<float>(c, r) = static_cast<float>(50.0 + 40.0 * y * y * y);
      lab.a.at<float>(c, r) = 0.0f;
      lab.b.at<float>(c, r) = -5.0f;
    }
  return lab;
}

TEST(SkyModel, FitsTheSkyAboveTheBoundary) {
  const int cols = 64, rows = 101;
  const LabPlanes lab = CubicSky(cols, rows);
  SkyModel model;
  ASSERT_TRUE(model.Fit(lab, std::vector<int>(cols, rows), 1, 1.0f));
  cv::Mat dev;
  model.Deviation(lab, dev);
  for (int c = 0; c < cols; c += 7)
    for (int r = 0; r < rows; r += 5) EXPECT_LT(dev.at<float>(c, r), 0.05f) << c << " " << r;
}

TEST(SkyModel, ContinuesLinearlyBelowTheFittedRows) {
  // Fitted above y = 0.3 only: below, the expected sky colour continues the
  // tangent at the last fitted row, not the cubic, which at y = 0.9 reaches
  // L 79 (the lightness of snow under that sky).
  const int cols = 64, rows = 101, top = 31;
  LabPlanes lab = CubicSky(cols, rows);
  SkyModel model;
  ASSERT_TRUE(model.Fit(lab, std::vector<int>(cols, top), 1, 1.0f));
  const double y0 = (top - 1) / 100.0, y = 0.9;
  const double linear = 50.0 + 40.0 * y0 * y0 * y0 + 120.0 * y0 * y0 * (y - y0);
  for (int c = 0; c < cols; ++c) lab.l.at<float>(c, 90) = static_cast<float>(linear);
  cv::Mat dev;
  model.Deviation(lab, dev);
  for (int c = 0; c < cols; c += 9) {
    EXPECT_LT(dev.at<float>(c, 90), 1.5f) << c;  // the continued sky: sky (within the 1 delta E floor)
    EXPECT_GT(dev.at<float>(c, 89), 15.0f) << c;  // the cubic's own value (L ~ 78): not sky
    EXPECT_LT(dev.at<float>(c, 20), 0.05f) << c;  // fitted rows unchanged
  }
}

}  // namespace
}  // namespace horizonreg::skyline_detail
