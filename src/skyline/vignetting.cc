// SPDX-License-Identifier: MIT
#include "skyline/vignetting.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "skyline/refine.h"

namespace horizonreg {
namespace {

constexpr int kWorkSide = 256;           // the estimate reads a copy kWorkSide to 2 kWorkSide - 1 px across ...
constexpr int kBlockRows = 4;            // ... each pixel the mean of up to this many rows of its block
constexpr double kSmoothLogStep = 0.04;  // a pixel is smooth under this change of ln(light) per work px ...
constexpr double kMinLinear = 0.005;     // ... and counts where its light is above this (not black) ...
constexpr double kMaxLinear = 0.97;      // ... and no channel is clipped
constexpr double kCentreBand = 0.1;      // share of the width each side of the centre left out (the sign is unsure)
constexpr int kMinSamples = 500;         // fewer smooth pixels than this: no estimate
constexpr int kRounds = 8;               // rounds of the robust fit ...
constexpr double kHuberSigmas = 2.5;     // ... whose weights fall beyond this many robust sigmas
constexpr double kMaxGainStops = 3.0;    // Devignetted: the gain's cap
constexpr int kGainTable = 1024;         // Devignetted: entries of the gain over r^2 in [0, 1]

// The photo reduced by a whole factor k (returned) to kWorkSide to
// 2 kWorkSide - 1 px across, in linear light (sRGB read as gamma 2.2): ln
// of the channels' mean (NaN where it is under kMinLinear), and their
// maximum. Each work pixel is the mean of its k x k block over up to
// kBlockRows of its rows, in floats: a large photo is read in part, and
// the light is not rounded to 8 bits again (a fall-off of 2 stops changes
// it by about a grey level per work px, and the rounding pulls the
// estimate towards none).
int WorkLight(const cv::Mat& bgr, cv::Mat& log_light, cv::Mat& max_linear) {
  const int k = std::max(1, std::max(bgr.cols, bgr.rows) / kWorkSide);
  const int rows_read = std::min(k, kBlockRows);
  cv::Mat f(bgr.rows / k, bgr.cols / k, CV_32FC3, cv::Scalar::all(0));
  const float scale = 1.0f / (255.0f * k * rows_read);
  for (int j = 0; j < f.rows; ++j) {
    cv::Vec3f* q = f.ptr<cv::Vec3f>(j);
    for (int i = 0; i < rows_read; ++i) {
      const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(j * k + (2 * i + 1) * k / (2 * rows_read));
      for (int c = 0; c < f.cols; ++c, p += k) {
        int s0 = 0, s1 = 0, s2 = 0;
        for (int x = 0; x < k; ++x) s0 += p[x][0], s1 += p[x][1], s2 += p[x][2];
        q[c] += cv::Vec3f(s0 * scale, s1 * scale, s2 * scale);
      }
    }
  }
  cv::pow(f, 2.2, f);
  log_light.create(f.size(), CV_32F);
  max_linear.create(f.size(), CV_32F);
  for (int r = 0; r < f.rows; ++r) {
    const cv::Vec3f* p = f.ptr<cv::Vec3f>(r);
    float* l = log_light.ptr<float>(r);
    float* m = max_linear.ptr<float>(r);
    for (int c = 0; c < f.cols; ++c) {
      const float mean = (p[c][0] + p[c][1] + p[c][2]) / 3.0f;
      l[c] = mean > kMinLinear ? std::log(mean) : std::numeric_limits<float>::quiet_NaN();
      m[c] = std::max({p[c][0], p[c][1], p[c][2]});
    }
  }
  return k;
}

}  // namespace

Vignetting EstimateVignetting(const cv::Mat& bgr) {
  CV_Assert(bgr.type() == CV_8UC3);
  if (bgr.cols < 8 || bgr.rows < 8) return {};
  cv::Mat light, most;
  const int k = WorkLight(bgr, light, most);
  const int w = light.cols, h = light.rows;
  if (w < 8 || h < 8) return {};
  // The photo's centre and half-diagonal in work px.
  const double cx = 0.5 * bgr.cols / k - 0.5, cy = 0.5 * bgr.rows / k - 0.5;
  const double r2_corner = 0.25 * (bgr.cols * bgr.cols + bgr.rows * bgr.rows) / (static_cast<double>(k) * k);
  const double smooth = kSmoothLogStep * kWorkSide / std::max(w, h);
  // Per smooth pixel: its change of ln(light) along the row, pointing away
  // from the centre (d), and the model's regressors (ln gain's change along
  // the row, away from the centre, is (2 a + 4 b r^2) |x - cx| / r2_corner).
  std::vector<double> d, u, v;
  for (int r = 1; r + 1 < h; ++r) {
    const float* up = light.ptr<float>(r - 1);
    const float* at = light.ptr<float>(r);
    const float* down = light.ptr<float>(r + 1);
    const float* m = most.ptr<float>(r);
    const double dy = r - cy;
    for (int c = 1; c + 1 < w; ++c) {
      const double dx = c - cx;
      if (std::abs(dx) <= kCentreBand * w || !(m[c] < kMaxLinear)) continue;
      const double gx = 0.5 * (at[c + 1] - at[c - 1]), gy = 0.5 * (down[c] - up[c]);
      // NaN (a black neighbour) fails too.
      if (!(std::isfinite(at[c]) && gx * gx + gy * gy < smooth * smooth)) continue;
      const double r2 = (dx * dx + dy * dy) / r2_corner;
      d.push_back(dx > 0 ? gx : -gx);
      u.push_back(2.0 * std::abs(dx) / r2_corner);
      v.push_back(4.0 * r2 * std::abs(dx) / r2_corner);
    }
  }
  if (static_cast<int>(d.size()) < kMinSamples) return {};
  // Iteratively reweighted least squares (Huber's weights) of d on u and v.
  std::vector<double> weight(d.size(), 1.0), residual(d.size()), sorted;
  Vignetting out;
  for (int round = 0; round < kRounds; ++round) {
    double suu = 0, suv = 0, svv = 0, sud = 0, svd = 0;
    for (size_t i = 0; i < d.size(); ++i) {
      const double wt = weight[i];
      suu += wt * u[i] * u[i], suv += wt * u[i] * v[i], svv += wt * v[i] * v[i];
      sud += wt * u[i] * d[i], svd += wt * v[i] * d[i];
    }
    const double det = suu * svv - suv * suv;
    if (!(std::abs(det) > 1e-12 * suu * svv)) return {};
    out.a = (svv * sud - suv * svd) / det;
    out.b = (suu * svd - suv * sud) / det;
    for (size_t i = 0; i < d.size(); ++i) residual[i] = std::abs(d[i] - out.a * u[i] - out.b * v[i]);
    sorted = residual;
    const double scale = 1.4826 * skyline_detail::Quantile(sorted, 0.5) + 1e-9;
    for (size_t i = 0; i < d.size(); ++i) weight[i] = 1.0 / std::max(1.0, residual[i] / (kHuberSigmas * scale));
  }
  return out;
}

cv::Mat Devignetted(const cv::Mat& bgr, const Vignetting& v) {
  CV_Assert(bgr.type() == CV_8UC3);
  // The gain in the photo's gamma over r^2 (0 at the centre, 1 at the corners).
  std::vector<float> gain(kGainTable + 1);
  const double cap = kMaxGainStops * std::log(2.0);
  for (int k = 0; k <= kGainTable; ++k)
    gain[k] = static_cast<float>(std::exp(std::min(cap, -v.LogGain(static_cast<double>(k) / kGainTable)) / 2.2));
  const double cx = 0.5 * (bgr.cols - 1), cy = 0.5 * (bgr.rows - 1), r2_corner = std::max(cx * cx + cy * cy, 1e-9);
  cv::Mat out(bgr.size(), CV_8UC3);
  for (int r = 0; r < bgr.rows; ++r) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(r);
    cv::Vec3b* q = out.ptr<cv::Vec3b>(r);
    const double dy2 = (r - cy) * (r - cy);
    for (int c = 0; c < bgr.cols; ++c) {
      const double r2 = ((c - cx) * (c - cx) + dy2) / r2_corner;
      const float g = gain[std::min(kGainTable, static_cast<int>(r2 * kGainTable + 0.5))];
      for (int k = 0; k < 3; ++k) q[c][k] = cv::saturate_cast<uchar>(p[c][k] * g);
    }
  }
  return out;
}

}  // namespace horizonreg
