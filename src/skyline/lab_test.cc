// SPDX-License-Identifier: MIT
#include "skyline/lab.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace horizonreg {
namespace {

TEST(LabMaths, ExpLogisticAndCubeRootAreAccurate) {
  for (double x = -87.0; x <= 87.0; x += 0.01) {
    const float xf = static_cast<float>(x);
    ASSERT_NEAR(ExpApprox(xf) / std::exp(static_cast<double>(xf)), 1.0, 3e-7) << x;
  }
  for (double x = -16.0; x <= 16.0; x += 0.001)
    ASSERT_NEAR(Logistic(static_cast<float>(x)), 1.0 / (1.0 + std::exp(-x)), 2e-7) << x;
  for (double t = 1e-6; t <= 2.0; t *= 1.001)
    ASSERT_NEAR(CbrtApprox(static_cast<float>(t)) / std::cbrt(t), 1.0, 6e-7) << t;
}

TEST(LabMaths, LogisticIsClampedAwayFromSubnormals) {
  EXPECT_GT(Logistic(-1e6f), 1e-8f);
  EXPECT_LT(Logistic(1e6f), 1.0f);
  EXPECT_TRUE(std::isnormal(Logistic(-100.0f) * Logistic(-100.0f) * Logistic(-100.0f)));
}

// CIELAB (D65) of an 8-bit sRGB colour in double precision, by the
// definitions OpenCV documents for COLOR_BGR2Lab. (OpenCV's own float path
// interpolates tables and is off by up to ~0.3 near the cube root's toe.)
cv::Vec3d ReferenceLab(const cv::Vec3b& bgr) {
  auto linear = [](int v8) {
    const double v = v8 / 255.0;
    return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
  };
  const double b = linear(bgr[0]), g = linear(bgr[1]), r = linear(bgr[2]);
  auto f = [](double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; };
  const double fx = f((0.412453 * r + 0.357580 * g + 0.180423 * b) / 0.950456);
  const double fy = f(0.212671 * r + 0.715160 * g + 0.072169 * b);
  const double fz = f((0.019334 * r + 0.119193 * g + 0.950227 * b) / 1.088754);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

TEST(LabConverter, MatchesTheDefinitionForEveryColourOnALattice) {
  std::vector<cv::Vec3b> bgr;  // every 8-bit colour on a 15-step lattice, up to 255
  for (int b = 0; b < 18; ++b)
    for (int g = 0; g < 18; ++g)
      for (int r = 0; r < 18; ++r)
        bgr.emplace_back(std::min(255, 15 * b), std::min(255, 15 * g), std::min(255, 15 * r));
  const int n = static_cast<int>(bgr.size());
  std::vector<float> l(n), a(n), b(n);
  LabConverter::Instance().Convert(&bgr[0][0], 3, n, l.data(), a.data(), b.data());
  for (int k = 0; k < n; ++k) {
    const cv::Vec3d want = ReferenceLab(bgr[k]);
    ASSERT_NEAR(l[k], want[0], 2e-4) << k;
    ASSERT_NEAR(a[k], want[1], 5e-4) << k;
    ASSERT_NEAR(b[k], want[2], 5e-4) << k;
  }
}

TEST(LabConverter, TransposedPlanesHoldOneImageColumnPerRow) {
  cv::Mat bgr(7, 300, CV_8UC3);  // wider than a conversion block
  cv::randu(bgr, 0, 256);
  LabPlanes planes;
  LabConverter::Instance().ConvertTransposed(bgr, planes);
  ASSERT_EQ(planes.Rows(), 300);
  ASSERT_EQ(planes.Cols(), 7);
  float l, a, b;
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      LabConverter::Instance().Convert(bgr.ptr<uint8_t>(y, x), 3, 1, &l, &a, &b);
      ASSERT_EQ(planes.l.at<float>(x, y), l);
      ASSERT_EQ(planes.a.at<float>(x, y), a);
      ASSERT_EQ(planes.b.at<float>(x, y), b);
    }
}

}  // namespace
}  // namespace horizonreg
