// SPDX-License-Identifier: MIT
#include "skyline/band.h"

#include <cmath>
#include <opencv2/core.hpp>

#include "util/errors.h"

namespace horizonreg {

Skyline BandSkyline(const cv::Mat& frame, const std::vector<double>& predicted_y, double band_px, double min_contrast) {
  HR_CHECK(frame.type() == CV_8UC3) << "BandSkyline needs 8-bit BGR";
  HR_CHECK(static_cast<int>(predicted_y.size()) == frame.cols) << "one prediction per column";
  Skyline s;
  s.width = frame.cols;
  s.height = frame.rows;
  s.y.assign(frame.cols, NAN);
  s.confidence.assign(frame.cols, 0.0);
  const int h = frame.rows;
  std::vector<int> sum;  // per row: B + G + R of this column
  std::vector<double> scores;
  for (int c = 0; c < frame.cols; ++c) {
    const double p = predicted_y[c];
    if (!std::isfinite(p)) continue;
    const int lo = std::max(3, static_cast<int>(std::floor(p - band_px)));
    const int hi = std::min(h - 3, static_cast<int>(std::ceil(p + band_px)));
    if (hi - lo < 3) continue;
    sum.resize(hi - lo + 6);
    for (int r = lo - 3; r < hi + 3; ++r) {
      const cv::Vec3b& v = frame.at<cv::Vec3b>(r, c);
      sum[r - lo + 3] = v[0] + v[1] + v[2];
    }
    const auto [row, y, contrast] = StrongestStep(
        lo, hi,
        [&](int r) {  // mean of the three rows above against the three below
          const int i = r - lo + 3;
          return std::abs((sum[i - 1] + sum[i - 2] + sum[i - 3]) / 3.0 - (sum[i] + sum[i + 1] + sum[i + 2]) / 3.0);
        },
        scores);
    if (contrast < min_contrast) continue;
    s.y[c] = y;
    s.confidence[c] = std::min(1.0, contrast / (4.0 * std::max(1.0, min_contrast)));
  }
  return s;
}

cv::Mat AsBgr(const cv::Mat& frame) {
  if (frame.type() != CV_8UC1) return frame;
  const cv::Mat planes[3] = {frame, frame, frame};
  cv::Mat bgr;
  cv::merge(planes, 3, bgr);
  return bgr;
}

}  // namespace horizonreg
