// SPDX-License-Identifier: MIT
#include "skyline/vignetting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

namespace horizonreg {
namespace {

// A landscape 900 x 600: a sky lightening downwards over a rough terrain
// (blocks of random grey) from row 330, light noise everywhere.
cv::Mat Landscape() {
  cv::Mat img(600, 900, CV_8UC3);
  cv::RNG rng(5);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      cv::Vec3b& p = img.at<cv::Vec3b>(r, c);
      if (r < 330) {
        const double t = r / 330.0;
        p = cv::Vec3b(cv::saturate_cast<uchar>(215 + 25 * t + rng.gaussian(1.0)),
                      cv::saturate_cast<uchar>(170 + 40 * t + rng.gaussian(1.0)),
                      cv::saturate_cast<uchar>(120 + 50 * t + rng.gaussian(1.0)));
      } else {
        cv::RNG block(static_cast<uint64_t>((r / 6) * 1000 + c / 6 + 1));
        const int g = block.uniform(40, 200);
        p = cv::Vec3b(cv::saturate_cast<uchar>(g + rng.gaussian(1.0)), cv::saturate_cast<uchar>(g + 10),
                      cv::saturate_cast<uchar>(g - 10));
      }
    }
  return img;
}

// `img` under cos^4 vignetting in linear light (gamma 2.2), the angle's
// tangent `k` times the distance from the centre over half the width.
cv::Mat Vignetted(const cv::Mat& img, double k) {
  cv::Mat out = img.clone();
  const double cx = 0.5 * (img.cols - 1), cy = 0.5 * (img.rows - 1);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const double rr = std::hypot(c - cx, r - cy) / (0.5 * img.cols);
      const double g = std::pow(std::cos(std::atan(k * rr)), 4.0);
      cv::Vec3b& p = out.at<cv::Vec3b>(r, c);
      for (int ch = 0; ch < 3; ++ch) p[ch] = cv::saturate_cast<uchar>(p[ch] * std::pow(g, 1.0 / 2.2));
    }
  return out;
}

// The true corner loss of Vignetted(.., k) in stops for a 900 x 600 frame.
double TrueCornerStops(double k) {
  const double rr = std::hypot(449.5, 299.5) / 450.0;
  return 4.0 * std::log2(std::cos(std::atan(k * rr)));
}

TEST(EstimateVignetting, ReadsALensFallOffAndNoneInAFlatPhoto) {
  const cv::Mat flat = Landscape();
  EXPECT_GT(EstimateVignetting(flat).CornerStops(), -0.3);
  for (double k : {0.5, 0.9}) {
    const double truth = TrueCornerStops(k);
    const Vignetting v = EstimateVignetting(Vignetted(flat, k));
    EXPECT_NEAR(v.CornerStops(), truth, 0.35 * std::abs(truth)) << k;
  }
}

TEST(EstimateVignetting, ASkyLighteningDownwardsIsNoFallOff) {
  // Vertical changes alone (a sky's gradient) carry no fall-off: only the
  // changes along rows are read.
  cv::Mat img(400, 600, CV_8UC3);
  for (int r = 0; r < img.rows; ++r) img.row(r).setTo(cv::Scalar(120 + r / 4, 130 + r / 5, 100 + r / 5));
  EXPECT_NEAR(EstimateVignetting(img).CornerStops(), 0.0, 0.05);
}

TEST(Devignetted, UndoesTheFallOffItWasGiven) {
  const cv::Mat flat = Landscape();
  const cv::Mat dark = Vignetted(flat, 0.9);
  const Vignetting v = EstimateVignetting(dark);
  const cv::Mat back = Devignetted(dark, v);
  // The top corners' sky comes back within a few grey levels of the flat
  // photo's (it had lost about half its light).
  for (const cv::Point at : {cv::Point(20, 20), cv::Point(880, 20)}) {
    const cv::Scalar before = cv::mean(flat(cv::Rect(at.x - 15, at.y - 15, 30, 30)));
    const cv::Scalar lost = cv::mean(dark(cv::Rect(at.x - 15, at.y - 15, 30, 30)));
    const cv::Scalar after = cv::mean(back(cv::Rect(at.x - 15, at.y - 15, 30, 30)));
    EXPECT_GT(before[0] - lost[0], 50.0);
    EXPECT_NEAR(after[0], before[0], 0.25 * (before[0] - lost[0]));
  }
  // No fall-off: the photo as it was.
  const cv::Mat same = Devignetted(flat, Vignetting{});
  EXPECT_EQ(cv::norm(same, flat, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace horizonreg
