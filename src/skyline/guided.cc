// SPDX-License-Identifier: MIT
// GuideSkyline (skyline.h): the skyline read again near where a registered
// pose predicts it.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "skyline/refine.h"
#include "skyline/skyline.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

// At 1024 columns; rows scale with the width.
constexpr int kHalfColumns = 2;        // each column read averaged with 2 neighbours on each side
constexpr int kFitRows = 16;           // sky rows above a candidate row fitted by a quadratic
constexpr int kMinFitRows = 6;         // fewer above the window: not read
constexpr int kGapRows = 1;            // rows between the fitted sky and the candidate row
constexpr float kDepartSigmas = 4.0f;  // departure from the fit, in robust sigmas of its rows ...
constexpr float kDepartMin = 3.0f;     // ... and at least this (delta E: 1.5-2 let a sky's gradient pass)
constexpr float kUniform = 0.5f;       // the fitted rows' 90th-percentile residual, at most this share of the threshold
constexpr int kHeldRows = 6;           // the departure holds in 80% of the rows from it down to the extracted
constexpr float kHeldShare = 0.8f;     // boundary (at least 6, at most 12: a thin cloud has sky below it)
constexpr int kHeldMaxRows = 12;
constexpr double kMaxWindowPx = 40.0;  // rows read at most per column
constexpr int kOutlierHalf = 5;        // a re-read value within kOutlierPx of the median of 5 columns each side
constexpr double kOutlierPx = 3.0;

// Quadratic fits per CIELAB channel through rows i - f - 1 .. i - 2 of a
// strip (the row just above i is left out: a sloping edge averaged over
// neighbouring columns half fills it), in u = row - i; Departure(j) is row
// j's distance from them.
class SkyFit {
 public:
  SkyFit(const float* l, const float* a, const float* b) : ch_{l, a, b} {}
  void Fit(int i, int f) {
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    Eigen::Matrix3d v = Eigen::Matrix3d::Zero();  // column k: channel k's right-hand side
    for (int j = i - f - kGapRows; j < i - kGapRows; ++j) {
      const double u = j - i;
      const Eigen::Vector3d basis(1.0, u, u * u);
      m += basis * basis.transpose();
      for (int k = 0; k < 3; ++k) v.col(k) += basis * ch_[k][j];
    }
    coef_ = m.ldlt().solve(v);
    origin_ = i;
  }
  double Predict(int k, int j) const {
    const double u = j - origin_;
    return coef_(0, k) + coef_(1, k) * u + coef_(2, k) * u * u;
  }
  float Departure(int j) const {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (ch_[k][j] - Predict(k, j)) * (ch_[k][j] - Predict(k, j));
    return static_cast<float>(std::sqrt(d2));
  }
  float channel(int k, int j) const { return ch_[k][j]; }

 private:
  const float* ch_[3];
  Eigen::Matrix3d coef_ = Eigen::Matrix3d::Zero();
  int origin_ = 0;
};

// The first row from `lo` to `hi` (strip indices) whose f rows above are
// smooth sky and from which the strip departs from their fit and keeps
// departing down to held_to (a ridge, not a cloud over sky); -1 when none.
// `fit` holds that row's fit on return.
int SkyEnd(SkyFit& fit, int lo, int hi, int f, int held_to, int held_max, std::vector<float>& res) {
  res.resize(f);
  for (int i = lo; i <= hi; ++i) {
    fit.Fit(i, f);
    for (int j = 0; j < f; ++j) res[j] = fit.Departure(i - f - kGapRows + j);
    std::nth_element(res.begin(), res.begin() + f / 2, res.end());
    const float sigma = res[f / 2] / 1.5f;  // a 3-d residual's magnitude: its median is ~1.5 sigma
    const float thr = std::max(kDepartMin, kDepartSigmas * sigma);
    std::nth_element(res.begin(), res.begin() + (9 * f) / 10, res.end());
    if (res[(9 * f) / 10] > kUniform * thr || fit.Departure(i) <= thr) continue;
    const int end = std::clamp(held_to, i + kHeldRows, i + held_max);
    int held = 0;
    for (int j = i; j <= end; ++j) held += fit.Departure(j) > thr;
    if (held >= kHeldShare * (end - i + 1)) return i;
  }
  return -1;
}

}  // namespace

Skyline GuideSkyline(const cv::Mat& image, const Skyline& skyline, const std::vector<double>& predicted,
                     const std::vector<double>& above_px, const std::vector<double>& below_px) {
  const size_t n = static_cast<size_t>(skyline.width);
  if (image.type() != CV_8UC3 || image.cols != skyline.width || image.rows != skyline.height || skyline.y.size() != n ||
      predicted.size() != n || above_px.size() != n || below_px.size() != n)
    throw InvalidArgument(
        "GuideSkyline: the image (8-bit BGR), skyline, prediction and window must have the same width");
  const int w = image.cols, h = image.rows;
  Skyline out = skyline;
  out.y_alt.clear();  // one candidate per column
  const double scale = std::max(1.0, w / 1024.0);
  const int fit_rows = static_cast<int>(std::lround(kFitRows * scale));
  const int min_fit = static_cast<int>(std::lround(kMinFitRows * scale));
  // The longest window read, capped at kMaxWindowPx (per 1024 columns).
  double longest = 0.0;
  for (size_t x = 0; x < n; ++x)
    if (std::isfinite(predicted[x]) && above_px[x] >= 0.0 && below_px[x] >= 0.0)
      longest = std::max(longest, std::min(above_px[x] + below_px[x], kMaxWindowPx * scale));
  const int window = static_cast<int>(std::ceil(longest)) + 2;
  const int held_max = static_cast<int>(std::lround(kHeldMaxRows * scale));
  const int count = fit_rows + kGapRows + window + held_max + 1;
  // The columns to read: their extracted boundary lies below the window (a
  // boundary inside the window, or above it where the DEM lacks terrain the
  // photo shows, stays as extracted; a null one stays null: a tree or fog
  // hides the horizon there).
  std::vector<int> first(w, skyline_detail::RefineStrips::kNoStrip), lo(w, 0), hi(w, 0);
  for (int x = 0; x < w; ++x) {
    const double p = predicted[x], y = skyline.y[x], below = below_px[x];
    if (!std::isfinite(p) || !std::isfinite(y) || !(above_px[x] >= 0.0) || !(below >= 0.0) || y <= p + below) continue;
    const double above = std::min(above_px[x], kMaxWindowPx * scale - below);
    lo[x] = static_cast<int>(std::floor(p - above));
    hi[x] = std::min(h - 2 - skyline.overlay_bottom_rows, static_cast<int>(std::ceil(p + below)));
    const int f = std::min(fit_rows, lo[x] - kGapRows - skyline.overlay_top_rows);  // never within a strip
    if (f < min_fit || hi[x] <= lo[x]) continue;
    first[x] = lo[x] - fit_rows - kGapRows;  // rows above the image repeat its top row: the fit starts at lo - f - 1
  }
  skyline_detail::LabStrips lab;
  skyline_detail::AverageStrips(image, first, count, kHalfColumns, lab.bgr);
  lab.Convert();
  std::vector<uint8_t> reread(w, 0);
  std::vector<float> res;
  for (int x = 0; x < w; ++x) {
    if (first[x] == skyline_detail::RefineStrips::kNoStrip) continue;
    const size_t at = static_cast<size_t>(x) * count;
    SkyFit fit(lab.l.data() + at, lab.a.data() + at, lab.b.data() + at);
    const int f = std::min(fit_rows, lo[x] - kGapRows - skyline.overlay_top_rows);
    // The departure must hold down to the extracted boundary.
    const int held_to = static_cast<int>(std::floor(skyline.y[x])) - 1 - first[x];
    const int i = SkyEnd(fit, lo[x] - first[x], hi[x] - first[x], f, held_to, held_max, res);
    if (i < 0) continue;
    // The half-way crossing from the fitted sky to the colour of the 3 rows
    // below the departure, next to it.
    double g[3] = {0, 0, 0};
    for (int j = i + 1; j <= i + 3; ++j)
      for (int k = 0; k < 3; ++k) g[k] += fit.channel(k, j) / 3.0;
    auto share = [&](int j) {  // 1 sky, 0 ground
      double num = 0, den = 0;
      for (int k = 0; k < 3; ++k) {
        const double d = fit.Predict(k, j) - g[k];
        num += (fit.channel(k, j) - g[k]) * d, den += d * d;
      }
      return den > 1e-9 ? num / den : 0.0;
    };
    const double crossing = skyline_detail::HalfWayCrossing(std::max(1, i - 1), i + 2, share);
    out.y[x] = first[x] + (std::isfinite(crossing) ? crossing : i);
    out.confidence[x] = std::clamp(fit.Departure(i + 2) / 20.0, 0.05, 1.0);
    reread[x] = 1;
  }
  // A re-read value far from the median of its neighbours (a thin cloud, a
  // band of haze) keeps the extracted one.
  const int half = static_cast<int>(std::lround(kOutlierHalf * scale));
  std::vector<double> near, y = out.y;
  for (int x = 0; x < w; ++x) {
    if (!reread[x]) continue;
    near.clear();
    for (int k = std::max(0, x - half); k <= std::min(w - 1, x + half); ++k)
      if (k != x && std::isfinite(out.y[k])) near.push_back(out.y[k]);
    if (near.size() < 3) continue;
    const double median = skyline_detail::Quantile(near, 0.5);
    if (std::abs(out.y[x] - median) > kOutlierPx * scale)
      y[x] = skyline.y[x], out.confidence[x] = skyline.confidence[x];
  }
  out.y = std::move(y);
  return out;
}

}  // namespace horizonreg
