// SPDX-License-Identifier: MIT
// The skyline extractor's colour space: CIELAB (D65, L 0..100, as OpenCV
// defines it) held as three float planes, and the elementwise maths of its
// per-pixel loops written so that GCC vectorises them (std::exp and a table
// lookup per pixel do not vectorise; these have no branches, calls or
// gathers). Internal to the skyline module.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

#include "util/vector_clones.h"  // HR_VECTOR_CLONES on the per-pixel loops

namespace horizonreg {

// e^x for x in [-87, 87] (not checked: a clamp here let GCC evaluate
// e^-87 times the caller's factors in every lane, a subnormal product that
// costs ~100 cycles), |relative error| < 2e-7 (Cephes' expf: range reduction
// by ln 2 and a degree-6 polynomial).
inline float ExpApprox(float x) {
  const float n = (x * 1.44269504f + 12582912.0f) - 12582912.0f;  // round to nearest: 1.5 * 2^23
  const float r = (x - n * 0.693359375f) + n * 2.12194440e-4f;    // x - n ln 2, in two parts
  float p = 1.9875691500e-4f;
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * r * r + r + 1.0f;
  return p * std::bit_cast<float>((static_cast<int32_t>(n) + 127) << 23);  // times 2^n
}

// The logistic function 1 / (1 + e^-x), |error| < 1e-7, with x clamped to
// [-16, 16] (values 1e-7 from 0 or 1): products of a few such factors then
// stay clear of subnormal floats, which cost ~100 cycles per operation.
inline float Logistic(float x) {
  x = x < -16.0f ? -16.0f : x;
  x = x > 16.0f ? 16.0f : x;
  return 1.0f / (1.0f + ExpApprox(-x));
}

// The cube root of t in [1e-6, 2], |relative error| < 5e-7: a bit-level
// first guess of t^(-1/3) and three Newton steps (t^(-1/3) needs no division).
inline float CbrtApprox(float t) {
  const int32_t bits = std::bit_cast<int32_t>(t);
  float r = std::bit_cast<float>(0x54a21d2a - static_cast<int32_t>(static_cast<float>(bits) * (1.0f / 3)));
  const float t_third = t * (1.0f / 3);
  for (int i = 0; i < 3; ++i) {  // r (4 - t r^3) / 3, with a shorter chain of dependent products
    const float r2 = r * r;
    r = r * (4.0f / 3) - t_third * (r2 * r2);
  }
  return t * r * r;
}

// CIELAB of an image as planes; the extractor keeps them transposed (one
// row per image column), so a column's pixels are contiguous.
struct LabPlanes {
  cv::Mat l, a, b;  // CV_32F
  void Create(int rows, int cols);
  int Rows() const { return l.rows; }
  int Cols() const { return l.cols; }
};

// 8-bit sRGB (BGR order) to CIELAB. Written out because OpenCV's cvtColor
// spends ~120 ms building its Lab tables on first use, which a one-shot
// command pays every time.
class LabConverter {
 public:
  static const LabConverter& Instance();

  // CIELAB of n pixels, pixel i at bgr + i * step (bytes), into l, a, b[0, n).
  void Convert(const uint8_t* bgr, std::ptrdiff_t step, int n, float* l, float* a, float* b) const;
  // The image (8-bit BGR) transposed into planes: row c of each plane is
  // column c of the image.
  void ConvertTransposed(const cv::Mat& bgr, LabPlanes& lab) const;

 private:
  LabConverter();
  float linear_[256];  // sRGB 8-bit value to linear light
};

}  // namespace horizonreg
