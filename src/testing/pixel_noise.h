// SPDX-License-Identifier: MIT
// Test helper: a camera's pixel noise added to an 8-bit image.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace horizonreg::testing {

// Gaussian noise of `sigma` levels per channel, saturated to 8 bits;
// seeded, so every run adds the same noise.
inline void AddPixelNoise(cv::Mat& img, double sigma, uint64_t seed = 7) {
  cv::Mat noise(img.size(), CV_16SC(img.channels())), wide;
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  img.convertTo(wide, CV_16SC(img.channels()));
  wide += noise;
  wide.convertTo(img, img.type());
}

}  // namespace horizonreg::testing
