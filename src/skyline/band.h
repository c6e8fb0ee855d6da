// SPDX-License-Identifier: MIT
// The skyline near a prediction: per column the strongest colour step inside
// a band around a predicted y (tracking a video, re-reading a near miss).
#pragma once

#include <algorithm>
#include <vector>

#include "skyline/skyline.h"

namespace horizonreg {

// The skyline in a band around `predicted_y` (per column, NaN where there is
// no prediction): per column the strongest colour step (mean of three rows
// above against three below), sub-pixel, NaN where weaker than min_contrast.
// `frame` is 8-bit BGR.
Skyline BandSkyline(const cv::Mat& frame, const std::vector<double>& predicted_y, double band_px, double min_contrast);

// 8-bit grey frames as BGR; anything else is returned as it is.
cv::Mat AsBgr(const cv::Mat& frame);

// The boundary r in [lo, hi] (between rows r - 1 and r) with the highest
// score(r), and its y refined to sub-pixel by a parabola through its
// neighbours' scores. lo <= hi. `scores` is scratch space.
struct Step {
  int row;
  double y, score;
};
template <typename Score>
Step StrongestStep(int lo, int hi, Score score, std::vector<double>& scores) {
  scores.assign(hi - lo + 1, 0.0);
  int best = 0;
  for (int r = lo; r <= hi; ++r) {
    scores[r - lo] = score(r);
    if (scores[r - lo] > scores[best]) best = r - lo;
  }
  double y = lo + best;
  if (best > 0 && best + 1 < static_cast<int>(scores.size())) {
    const double a = scores[best - 1], b = scores[best], d = scores[best + 1], denom = a - 2 * b + d;
    if (denom < 0) y += std::clamp(0.5 * (a - d) / denom, -0.5, 0.5);
  }
  return {lo + best, y, scores[best]};
}

}  // namespace horizonreg
