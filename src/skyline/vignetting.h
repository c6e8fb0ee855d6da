// SPDX-License-Identifier: MIT
// Lens vignetting: a photo darkening towards its corners (a wide lens wide
// open, a cheap webcam's), read from the photo itself and divided out before
// the skyline is sought.
#pragma once

#include <cmath>
#include <opencv2/core.hpp>

namespace horizonreg {

// A radial fall-off of light: the log of the gain in linear light is
// a r^2 + b r^4 (never above 0), r the distance from the image's centre
// over its half-diagonal (1 at the corners).
struct Vignetting {
  double a = 0.0, b = 0.0;
  double LogGain(double r2) const { return std::min(0.0, a * r2 + b * r2 * r2); }
  // The corners' loss of light, in stops (negative: darker).
  double CornerStops() const { return LogGain(1.0) / std::log(2.0); }
};

// The fall-off read from an 8-bit BGR photo by the symmetry of its
// gradients (Zheng et al., "Single-image vignetting correction using radial
// gradient symmetry", CVPR 2008): over the smooth parts of a scene (sky,
// snow, haze) the log of linear light changes as often one way as the other
// along a row, so the horizontal changes that point away from the centre
// more than towards it are the lens's. Fitted robustly to those changes in
// a copy 256-511 px across; the vertical changes are left out (the sky
// darkens upwards by itself). A zero fall-off when too little of the photo
// is smooth.
Vignetting EstimateVignetting(const cv::Mat& bgr);

// `bgr` with the fall-off `v` divided out (the gain capped at 3 stops), in
// the photo's gamma (2.2): each pixel times the gain's 2.2th root.
cv::Mat Devignetted(const cv::Mat& bgr, const Vignetting& v);

}  // namespace horizonreg
