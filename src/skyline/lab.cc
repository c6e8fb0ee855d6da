// SPDX-License-Identifier: MIT
#include "skyline/lab.h"

#include <cmath>

namespace horizonreg {
namespace {

// CIELAB's f(t): the cube root, or its linear toe near black.
inline float LabF(float t) {
  const float toe = 7.787f * t + 16.0f / 116.0f;
  const float root = CbrtApprox(t < 1e-6f ? 1e-6f : t);
  return t > 0.008856f ? root : toe;
}

// CIELAB of n pixels from their linear r, g, b (no array overlaps another:
// without __restrict GCC would need more run-time overlap tests than it makes
// before vectorising).
HR_VECTOR_CLONES void LabFromLinear(const float* __restrict lin_r, const float* __restrict lin_g,
                                    const float* __restrict lin_b, int n, float* __restrict l, float* __restrict a,
                                    float* __restrict b) {
  for (int i = 0; i < n; ++i) {
    const float r = lin_r[i], g = lin_g[i], bl = lin_b[i];
    const float fx = LabF((0.412453f * r + 0.357580f * g + 0.180423f * bl) * (1.0f / 0.950456f));
    const float fy = LabF(0.212671f * r + 0.715160f * g + 0.072169f * bl);
    const float fz = LabF((0.019334f * r + 0.119193f * g + 0.950227f * bl) * (1.0f / 1.088754f));
    l[i] = 116.0f * fy - 16.0f;
    a[i] = 500.0f * (fx - fy);
    b[i] = 200.0f * (fy - fz);
  }
}

}  // namespace

void LabPlanes::Create(int rows, int cols) {
  l.create(rows, cols, CV_32F);
  a.create(rows, cols, CV_32F);
  b.create(rows, cols, CV_32F);
}

const LabConverter& LabConverter::Instance() {
  static const LabConverter converter;
  return converter;
}

LabConverter::LabConverter() {
  for (int i = 0; i < 256; ++i) {
    const double v = i / 255.0;
    linear_[i] = static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
  }
}

void LabConverter::Convert(const uint8_t* bgr, std::ptrdiff_t step, int n, float* l, float* a, float* b) const {
  // In blocks: the table lookups first (scalar), then the arithmetic, which
  // vectorises.
  constexpr int kBlock = 256;
  float lin_r[kBlock], lin_g[kBlock], lin_b[kBlock];
  for (int start = 0; start < n; start += kBlock) {
    const int m = std::min(kBlock, n - start);
    for (int i = 0; i < m; ++i) {
      const uint8_t* p = bgr + (start + i) * step;
      lin_b[i] = linear_[p[0]], lin_g[i] = linear_[p[1]], lin_r[i] = linear_[p[2]];
    }
    LabFromLinear(lin_r, lin_g, lin_b, m, l + start, a + start, b + start);
  }
}

void LabConverter::ConvertTransposed(const cv::Mat& bgr, LabPlanes& lab) const {
  CV_Assert(bgr.type() == CV_8UC3);
  lab.Create(bgr.cols, bgr.rows);
  for (int c = 0; c < bgr.cols; ++c)
    Convert(bgr.ptr<uint8_t>(0) + 3 * c, static_cast<std::ptrdiff_t>(bgr.step[0]), bgr.rows, lab.l.ptr<float>(c),
            lab.a.ptr<float>(c), lab.b.ptr<float>(c));
}

}  // namespace horizonreg
