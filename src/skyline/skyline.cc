// SPDX-License-Identifier: MIT
#include "skyline/skyline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

constexpr int kHistBins = 16;             // per CIELAB axis
constexpr float kColourWeight = 0.25f;    // DP cost per misclassified pixel (edges weigh 1 per delta E)
constexpr float kEdgeAboveWeight = 0.5f;  // DP cost per delta E of sharp steps left above the boundary
constexpr float kEdgeNoise = 4.0f;        // delta E of a step that is still noise or a soft cloud edge
constexpr float kEdgeCap = 12.0f;         // delta E above which a step counts as fully an edge
constexpr float kSnowEdgeBoost = 4.0f;    // extra weight of a sharp step into white (snow) left above the boundary
constexpr float kDeepBlueB = -25.0f;      // b* below which a pixel is saturated blue: sky, never terrain
constexpr float kTopStepShare = 0.4f;     // refinement: the topmost step at least this share of the strongest wins
constexpr float kTopStepMin = 5.0f;       // ... and at least this delta E (noise in the sky stays below)
constexpr int kStepColumns = 2;           // refinement: steps read from the column averaged with 2 on each side
constexpr double kFogSpreadRows = 2.4;  // median contrast / largest one-row step above which a faint boundary is a fade
constexpr float kTreeGreen = 7.0f;      // -a* above which a dark boundary is a tree (dark shaded terrain is greyer)

inline int HistIndex(const cv::Vec3f& lab) {
  const int l = std::clamp(static_cast<int>(lab[0] * (kHistBins / 100.0f)), 0, kHistBins - 1);
  const int a = std::clamp(static_cast<int>((lab[1] + 64.0f) * (kHistBins / 128.0f)), 0, kHistBins - 1);
  const int b = std::clamp(static_cast<int>((lab[2] + 64.0f) * (kHistBins / 128.0f)), 0, kHistBins - 1);
  return (l * kHistBins + a) * kHistBins + b;
}

// The logistic function, from a table (linear interpolation, error < 1e-5;
// exp() per pixel was a third of the extraction time).
class SigmoidTable {
 public:
  SigmoidTable() {
    for (int i = 0; i <= kN; ++i) t_[i] = static_cast<float>(1.0 / (1.0 + std::exp(-(i * kStep - kRange))));
    t_[kN + 1] = t_[kN];
  }
  float operator()(float x) const {
    const float u = (std::clamp(x, -kRange, kRange) + kRange) * (1.0f / kStep);
    const int i = static_cast<int>(u);
    return t_[i] + (u - i) * (t_[i + 1] - t_[i]);
  }

 private:
  static constexpr float kRange = 16.0f, kStep = 1.0f / 64;
  static constexpr int kN = static_cast<int>(2 * kRange / kStep);
  std::array<float, kN + 2> t_{};
};

// The q-quantile (0..1) of a non-empty sample (reorders it).
double Quantile(std::vector<double>& v, double q) {
  const auto it = v.begin() + std::min(v.size() - 1, static_cast<size_t>(q * v.size()));
  std::nth_element(v.begin(), it, v.end());
  return *it;
}

inline float Sigmoid(float x) {
  static const SigmoidTable table;
  return table(x);
}

// 8-bit sRGB (BGR order) to CIELAB (D65; L 0..100), as OpenCV defines it.
// Written out because OpenCV's cvtColor spends ~120 ms building its Lab
// tables on first use, which a one-shot command pays every time.
class LabConverter {
 public:
  LabConverter() {
    for (int i = 0; i < 256; ++i) {
      const double v = i / 255.0;
      linear_[i] = static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
    }
    for (int i = 0; i <= kLut + 1; ++i) {  // f(t) = cbrt(t), or its linear toe, on [0, 1.1]
      const double t = 1.1 * i / kLut;
      f_[i] = static_cast<float>(t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0);
    }
  }
  cv::Vec3f operator()(const cv::Vec3b& bgr) const {
    const float b = linear_[bgr[0]], g = linear_[bgr[1]], r = linear_[bgr[2]];
    const float fx = F((0.412453f * r + 0.357580f * g + 0.180423f * b) / 0.950456f);
    const float fy = F(0.212671f * r + 0.715160f * g + 0.072169f * b);
    const float fz = F((0.019334f * r + 0.119193f * g + 0.950227f * b) / 1.088754f);
    return {116.0f * fy - 16.0f, 500.0f * (fx - fy), 200.0f * (fy - fz)};
  }
  // CIELAB of a whole 8-bit BGR image.
  void Convert(const cv::Mat& bgr, cv::Mat& lab) const {
    lab.create(bgr.rows, bgr.cols, CV_32FC3);
    for (int r = 0; r < bgr.rows; ++r) {
      const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
      cv::Vec3f* out = lab.ptr<cv::Vec3f>(r);
      for (int c = 0; c < bgr.cols; ++c) out[c] = (*this)(in[c]);
    }
  }

 private:
  static constexpr int kLut = 4096;
  float F(float t) const {
    const float x = std::clamp(t, 0.0f, 1.1f) * (kLut / 1.1f);
    const int i = static_cast<int>(x);
    return f_[i] + (x - i) * (f_[i + 1] - f_[i]);
  }
  std::array<float, 256> linear_{};
  std::array<float, kLut + 2> f_{};
};

// The mean of each 2 x 2 block (a half-size image; an odd last row or
// column averages what it has). cv::resize spends ~0.6 ms per call on this
// for three-channel float images.
void Halve(const cv::Mat& m, cv::Mat& out) {
  const int rows = (m.rows + 1) / 2, cols = (m.cols + 1) / 2;
  out.create(rows, cols, CV_32FC3);
  for (int r = 0; r < rows; ++r) {
    const cv::Vec3f* a = m.ptr<cv::Vec3f>(2 * r);
    const cv::Vec3f* b = m.ptr<cv::Vec3f>(std::min(2 * r + 1, m.rows - 1));
    cv::Vec3f* o = out.ptr<cv::Vec3f>(r);
    for (int c = 0; c < cols; ++c) {
      const int c1 = std::min(2 * c + 1, m.cols - 1);
      o[c] = 0.25f * (a[2 * c] + a[c1] + b[2 * c] + b[c1]);
    }
  }
}

// Pass 1: sky likeness relative to the image's top band (assumed sky).
// lab_t is transposed (one row per image column).
void SkyScoreFromTopBand(const cv::Mat& lab_t, cv::Mat& s) {
  const int w = lab_t.rows, h = lab_t.cols;
  const int band = std::max(2, h / 30);
  std::vector<float> ls;
  for (int c = 0; c < w; ++c)
    for (int r = 0; r < band; ++r) ls.push_back(lab_t.at<cv::Vec3f>(c, r)[0]);
  auto median = [](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const float lm = median(ls);
  s.create(w, h, CV_32F);
  for (int c = 0; c < w; ++c) {
    const cv::Vec3f* row = lab_t.ptr<cv::Vec3f>(c);
    float* out = s.ptr<float>(c);
    // Reference lightness: the lightest blue sky seen so far down this
    // column (skies lighten towards the horizon; white clouds are left out).
    float ref = lm;
    for (int r = 0; r < h; ++r) {
      const cv::Vec3f v = row[r];
      // Sky: not darker than the sky above it, blue or neutral in hue
      // (clouds, haze); terrain is darker or green, yellow, brown or red.
      const float dark = Sigmoid(((ref - 6.0f) - v[0]) / 2.5f);
      const float warm = std::min(1.0f, Sigmoid((v[2] - 6.0f) / 2.0f) + Sigmoid((std::abs(v[1]) - 10.0f) / 2.0f));
      // Saturated blue is sky however dark (deep sky, sky below distant
      // terrain); haze on far ridges is paler than that.
      const float deep_blue = Sigmoid((kDeepBlueB - v[2]) / 3.0f);
      out[r] = std::max((1.0f - dark), deep_blue) * (1.0f - warm);
      if (v[2] < -8.0f && out[r] > 0.5f) ref = std::max(ref, v[0]);
    }
  }
}

// Pass 2: sky probability from colour histograms of the pixels above and
// below a first boundary (class-balanced likelihood ratio).
void SkyScoreFromHistograms(const cv::Mat& lab_t, const std::vector<int>& boundary, cv::Mat& s) {
  const int w = lab_t.rows, h = lab_t.cols;
  std::vector<float> sky(kHistBins * kHistBins * kHistBins, 1.0f), ground(sky.size(), 1.0f);
  double ns = sky.size(), ng = ground.size();
  s.create(w, h, CV_32F);
  for (int c = 0; c < w; ++c) {
    const cv::Vec3f* row = lab_t.ptr<cv::Vec3f>(c);
    float* bin = s.ptr<float>(c);  // each pixel's bin for now (exact in a float)
    for (int r = 0; r < h; ++r) {
      const int i = HistIndex(row[r]);
      bin[r] = static_cast<float>(i);
      if (r < boundary[c] - 2) {
        sky[i] += 1, ns += 1;
      } else if (r > boundary[c] + 2) {
        ground[i] += 1, ng += 1;
      }
    }
  }
  std::vector<float> p(sky.size());
  for (size_t i = 0; i < p.size(); ++i) {
    const double ps = sky[i] / ns, pg = ground[i] / ng;
    p[i] = static_cast<float>(std::clamp(ps / (ps + pg), 0.02, 0.98));
  }
  for (int c = 0; c < w; ++c) {
    float* out = s.ptr<float>(c);
    for (int r = 0; r < h; ++r) out[r] = p[static_cast<int>(out[r])];
  }
}

// Colour step between rows y-1 and y: delta E between the means of rows
// (y, y+1) and (y-2, y-1), for y in [0, h]. Steps
// where the upper side is darker count half (sky is usually the brighter
// side). One row per image column.
void BoundarySteps(const cv::Mat& lab_t, cv::Mat& e) {
  const int w = lab_t.rows, h = lab_t.cols;
  e.create(w, h + 1, CV_32F);
  for (int c = 0; c < w; ++c) {
    const cv::Vec3f* row = lab_t.ptr<cv::Vec3f>(c);
    float* out = e.ptr<float>(c);
    out[0] = out[h] = 0.0f;
    for (int y = 1; y < h; ++y) {
      const float* p0 = &row[std::max(y - 2, 0)][0];
      const float* p1 = &row[y - 1][0];
      const float* p2 = &row[y][0];
      const float* p3 = &row[std::min(y + 1, h - 1)][0];
      const float dl = 0.5f * (p2[0] + p3[0] - p0[0] - p1[0]), da = 0.5f * (p2[1] + p3[1] - p0[1] - p1[1]),
                  below_b = 0.5f * (p2[2] + p3[2]), db = below_b - 0.5f * (p0[2] + p1[2]);
      // Any clear edge may be the skyline, not only the strongest: the
      // reward saturates (a faint far ridge above a contrasty near one).
      const float mag = std::min(std::sqrt(dl * dl + da * da + db * db), kEdgeCap);
      // A step down into saturated blue is within the sky (a cloud's base,
      // the renderer's or a real sky's deep blue near the horizon): terrain
      // below the skyline is never that blue, even far and hazy. (Above
      // b* = kDeepBlueB + 24 the logistic is < 4e-4: skipped.)
      const float into_deep_blue = below_b > kDeepBlueB + 24.0f ? 0.0f : Sigmoid((kDeepBlueB - below_b) / 3.0f);
      out[y] = (dl > 2.0f ? 0.5f * mag : mag) * (1.0f - into_deep_blue);
    }
  }
}

// Cost of leaving the colour step at row y above the boundary: its excess
// over the noise level, unless it leads (within 2 rows) into blue sky, as at
// the sky dome's own horizon (`base`). A sharp step from blue into white is
// snow when no blue sky follows below it (clouds fade in softly and have sky
// under them): `extra` holds that boost, which the boundary pays only for
// steps below the last blue-sky row above it (`blue`, 1 per such row).
struct EdgePenalty {
  cv::Mat base, extra;  // CV_32F, one row per image column
  cv::Mat blue;         // CV_8U, 1 where the pixel is blue sky
};

void EdgeAbovePenalty(const cv::Mat& steps_t, const cv::Mat& sky_t, const cv::Mat& lab_t, EdgePenalty& pen) {
  const int w = sky_t.rows, h = sky_t.cols;
  pen.base.create(w, h, CV_32F);
  pen.extra.create(w, h, CV_32F);
  pen.blue.create(w, h, CV_8U);
  std::vector<float> blue(h);  // blue-sky likeness
  for (int c = 0; c < w; ++c) {
    const float* e = steps_t.ptr<float>(c);
    const float* s = sky_t.ptr<float>(c);
    const cv::Vec3f* lab = lab_t.ptr<cv::Vec3f>(c);
    float* base = pen.base.ptr<float>(c);
    float* extra = pen.extra.ptr<float>(c);
    uint8_t* is_blue = pen.blue.ptr<uint8_t>(c);
    for (int k = 0; k < h; ++k) {
      blue[k] = s[k] > 0.05f && lab[k][2] < 0.0f ? s[k] * Sigmoid((-lab[k][2] - 8.0f) / 2.0f) : 0.0f;
      is_blue[k] = blue[k] > 0.5f;
    }
    for (int y = 0; y < h; ++y) {
      if (e[y] <= kEdgeNoise) {
        base[y] = extra[y] = 0.0f;
        continue;
      }
      const float blue_sky = std::max({blue[y], blue[std::min(y + 1, h - 1)], blue[std::min(y + 2, h - 1)]});
      const cv::Vec3f& after = lab[std::min(y + 2, h - 1)];
      const float white = Sigmoid((after[0] - 80.0f) / 3.0f) * Sigmoid((6.0f - std::abs(after[2])) / 2.0f);
      base[y] = (e[y] - kEdgeNoise) * (1.0f - blue_sky);
      extra[y] = base[y] * kSnowEdgeBoost * white;
    }
  }
}

// Globally best boundary (one y in [0, h] per column): misclassified pixels
// (sky below or non-sky above) minus the colour step at the boundary, plus
// `smoothness` per pixel of jump, around the slope expected from the roll.
std::vector<int> SolveBoundary(const cv::Mat& sky_t, const cv::Mat& steps_t, const EdgePenalty& penalty,
                               double smoothness, double edge_weight, double slope_px_per_col,
                               std::vector<float>& acc) {
  const int w = sky_t.rows, h = sky_t.cols, n = h + 1;
  std::vector<float> prev(n), cur(n), data(n), tmp(n), pen(n + 1), pen_extra(n + 1);
  const float beta = static_cast<float>(smoothness), lambda = static_cast<float>(edge_weight);
  auto data_cost = [&](int c) {
    const float* s = sky_t.ptr<float>(c);
    const float* e = steps_t.ptr<float>(c);
    float below = 0;
    for (int r = 0; r < h; ++r) below += s[r];
    // Sharp colour steps above the boundary are terrain edges left in the
    // sky (the paper scans from the top for the first edge): each costs its
    // excess over the noise level, unless it leads into sky-coloured pixels
    // (within 2 rows). Steps within 2 rows above the boundary are its own
    // (the 4-tap step spreads an edge over 3 rows).
    const float* p = penalty.base.ptr<float>(c);
    const float* px = penalty.extra.ptr<float>(c);
    const uint8_t* blue = penalty.blue.ptr<uint8_t>(c);
    pen[0] = pen_extra[0] = 0;
    for (int y = 0; y < h; ++y) pen[y + 1] = pen[y] + p[y], pen_extra[y + 1] = pen_extra[y] + px[y];
    float above = 0;
    int after_blue = 0;  // first row below the last blue-sky row above the boundary's margin
    for (int y = 0; y <= h; ++y) {
      const int top = std::max(0, y - 2);  // rows [0, top) lie above the boundary's own step
      if (top > 0 && blue[top - 1]) after_blue = top;
      const float snow = pen_extra[top] - pen_extra[std::min(after_blue, top)];
      data[y] = kColourWeight * (above + below) + kEdgeAboveWeight * (pen[top] + snow) - lambda * e[y];
      if (y < h) above += 1.0f - s[y], below -= s[y];
    }
  };
  data_cost(0);
  prev = data;
  acc.resize(static_cast<size_t>(w) * n);
  std::copy(prev.begin(), prev.end(), acc.begin());
  std::vector<int> shift(w, 0);  // rows the expected slope moves the boundary from column c - 1 to c
  for (int c = 1; c < w; ++c)
    shift[c] = static_cast<int>(std::lround(c * slope_px_per_col) - std::lround((c - 1) * slope_px_per_col));
  for (int c = 1; c < w; ++c) {
    // Shifted previous column, then an L1 distance transform (the argmins
    // are recovered when tracing back).
    for (int y = 0; y < n; ++y) tmp[y] = prev[std::clamp(y - shift[c], 0, h)];
    for (int y = 1; y < n; ++y) tmp[y] = std::min(tmp[y], tmp[y - 1] + beta);
    for (int y = n - 2; y >= 0; --y) tmp[y] = std::min(tmp[y], tmp[y + 1] + beta);
    data_cost(c);
    for (int y = 0; y < n; ++y) cur[y] = tmp[y] + data[y];
    std::swap(prev, cur);
    std::copy(prev.begin(), prev.end(), acc.begin() + static_cast<size_t>(c) * n);
  }
  std::vector<int> out(w);
  out[w - 1] = static_cast<int>(std::min_element(prev.begin(), prev.end()) - prev.begin());
  for (int c = w - 1; c > 0; --c) {
    // The previous column's row that reached out[c] most cheaply.
    const float* a = acc.data() + static_cast<size_t>(c - 1) * n;
    float best = INFINITY;
    int best_src = 0;
    for (int y = 0; y < n; ++y) {
      const int src = std::clamp(y - shift[c], 0, h);
      const float v = a[src] + beta * static_cast<float>(std::abs(out[c] - y));
      if (v < best) best = v, best_src = src;
    }
    out[c - 1] = best_src;
  }
  return out;
}

struct ColumnFit {
  double y = NAN;
  double contrast = 0;      // delta E between the local sky and ground colours
  double ground_l = 0;      // lightness just below the boundary
  double ground_green = 0;  // -a* just below the boundary (positive = green)
  double spread = 0;        // contrast / the largest one-row step: about 1-2 rows for an edge, more for a fade
};

// Sub-pixel boundary near row r0 of full-size column x: where the colour
// crosses half way from the local sky colour to the local ground colour.
ColumnFit RefineColumn(const cv::Mat& bgr, const LabConverter& to_lab, int x, double y0, int window) {
  const int h = bgr.rows, centre = static_cast<int>(std::lround(y0));
  // The column's colours over every row used below, converted once, and
  // those of the column averaged with kStepColumns neighbours on each side:
  // the steps that choose the boundary row are read from the average (pixel
  // noise in the sky would otherwise pass for the topmost clear step), the
  // crossing and the colours from the column itself.
  const int first = centre - window - 5, last = centre + window + 4;
  std::vector<cv::Vec3f> lab(last - first + 1), wide(last - first + 1);
  const int c0 = std::max(0, x - kStepColumns), c1 = std::min(bgr.cols - 1, x + kStepColumns), n = c1 - c0 + 1;
  for (int r = first; r <= last; ++r) {
    const cv::Vec3b* row = bgr.ptr<cv::Vec3b>(std::clamp(r, 0, h - 1));
    lab[r - first] = to_lab(row[x]);
    cv::Vec3i sum(0, 0, 0);
    for (int c = c0; c <= c1; ++c) sum += cv::Vec3i(row[c]);
    cv::Vec3b mean;
    for (int k = 0; k < 3; ++k) mean[k] = static_cast<uint8_t>((sum[k] + n / 2) / n);
    wide[r - first] = to_lab(mean);
  }
  auto at = [&](int r) { return lab[r - first]; };
  auto at_wide = [&](int r) { return wide[r - first]; };
  // The topmost clear step in the window (the paper scans each column from
  // the top for the first edge): a faint far ridge above a contrasty near
  // one is the skyline.
  std::vector<float> steps;
  std::vector<int> rows;
  int best = static_cast<int>(std::lround(y0));
  float best_step = -1;
  for (int r = static_cast<int>(std::lround(y0)) - window; r <= static_cast<int>(std::lround(y0)) + window; ++r) {
    if (r < 1 || r >= h) continue;
    const cv::Vec3f d = at_wide(r) - at_wide(r - 1);
    steps.push_back(std::sqrt(d.dot(d)));
    rows.push_back(r);
    if (steps.back() > best_step) best_step = steps.back(), best = r;  // the strongest, if no step is clear
  }
  for (size_t i = 0; i < steps.size(); ++i) {
    const bool local_max = (i == 0 || steps[i] >= steps[i - 1]) && (i + 1 == steps.size() || steps[i] >= steps[i + 1]);
    if (local_max && steps[i] >= kTopStepShare * best_step && steps[i] >= kTopStepMin) {
      best = rows[i];
      break;
    }
  }
  ColumnFit fit;
  if (best_step < 0) return fit;
  cv::Vec3f sky(0, 0, 0), ground(0, 0, 0);
  for (int k = 2; k <= 4; ++k) sky += at(best - 1 - k), ground += at(best + k);
  sky *= 1.0f / 3, ground *= 1.0f / 3;
  const cv::Vec3f d = sky - ground;
  const float dd = d.dot(d);
  fit.contrast = std::sqrt(dd);
  fit.spread = best_step > 0 ? fit.contrast / best_step : 0;
  fit.ground_l = ground[0];
  fit.ground_green = -ground[1];
  if (dd < 1e-6f) return fit;
  auto t = [&](int r) { return (at(r) - ground).dot(d) / dd; };  // 1 sky, 0 ground
  for (int r = best - 2; r <= best + 2; ++r) {
    const float t0 = t(r - 1), t1 = t(r);
    if (t0 >= 0.5f && t1 < 0.5f) {
      fit.y = (r - 0.5) + (t0 - 0.5) / (t0 - t1);
      return fit;
    }
  }
  fit.y = best;
  return fit;
}

std::vector<uint8_t> FindOccluders(const std::vector<ColumnFit>& fits, int image_rows) {
  // Occluders: trees and poles stand in front of the horizon as narrow
  // spikes with near-vertical flanks (terrain flanks are far less steep in
  // the image), or as dark green or black silhouettes, much darker than the
  // image's typical horizon terrain.
  const int w = static_cast<int>(fits.size());
  std::vector<uint8_t> occluded(w, 0);
  const double steep = 3.5;  // px of rise per column
  const int max_width = std::max(8, w / 8);
  auto y_at = [&](int x) { return fits[std::clamp(x, 0, w - 1)].y; };
  std::vector<int> flank(w, 0);  // -1 rising to the right, +1 falling
  // A flank: steep here and rising a good height over 6 columns.
  const double min_rise = std::max(15.0, 0.03 * image_rows);
  for (int x = 0; x < w; ++x) {
    const double d = 0.5 * (y_at(x + 1) - y_at(x - 1)), rise = y_at(x + 3) - y_at(x - 3);
    if (std::isfinite(d) && std::abs(d) > steep && std::abs(rise) > min_rise && d * rise > 0) flank[x] = d < 0 ? -1 : 1;
  }
  for (int x = 0; x < w; ++x) {
    if (flank[x] != -1) continue;
    // A rising flank, then a falling one within max_width (or the image edge).
    int end = -1;
    for (int k = x + 1; k < std::min(w, x + max_width); ++k)
      if (flank[k] == 1) end = k;
    if (end < 0 && w - x < max_width) end = w - 1;
    if (end >= 0) std::fill(occluded.begin() + x, occluded.begin() + end + 1, uint8_t{1});
  }
  for (int x = w - 1; x >= 0; --x)  // a falling flank near the left edge
    if (flank[x] == 1 && x < max_width && std::none_of(flank.begin(), flank.begin() + x, [](int f) { return f == -1; }))
      std::fill(occluded.begin(), occluded.begin() + x + 1, uint8_t{1});
  std::vector<double> lights;
  for (const ColumnFit& f : fits)
    if (std::isfinite(f.y)) lights.push_back(f.ground_l);
  const double typical_l = lights.empty() ? 0.0 : Quantile(lights, 0.5);
  for (int x = 0; x < w; ++x) {
    const ColumnFit& f = fits[x];
    const bool dark =
        f.ground_l < 12.0 || (f.ground_l < 35.0 && f.ground_l < 0.6 * typical_l && f.ground_green > kTreeGreen);
    if (std::isfinite(f.y) && dark) occluded[x] = 1;
  }
  return occluded;
}

// Scratch images of one extraction (work size; `_h` at half of it).
struct Workspace {
  cv::Mat reduced, small, small_t, lab_t, steps, sky, lab_h, steps_h, sky_h;
  EdgePenalty pen, pen_h;
  std::vector<float> acc;
};

// The image as 8-bit BGR (grey and BGRA converted, BGR shared).
cv::Mat ToBgr(const cv::Mat& image) {
  cv::Mat bgr;
  if (image.channels() == 1)
    cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  else if (image.channels() == 4)
    cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  else
    bgr = image;
  return bgr;
}

}  // namespace

void SkylineOptions::Check() const {
  auto fail = [](const char* field, double v, const char* rule) {
    std::ostringstream m;
    m << "SkylineOptions::" << field << " = " << v << "; violated: " << rule;
    throw InvalidArgument(m.str());
  };
  if (roll_hint_deg && !(std::abs(*roll_hint_deg) <= 45.0)) fail("roll_hint_deg", *roll_hint_deg, "|roll| <= 45");
  if (max_work_width_px < 64) fail("max_work_width_px", max_work_width_px, ">= 64");
  if (!(smoothness > 0.0)) fail("smoothness", smoothness, "> 0");
  if (!(edge_weight >= 0.0)) fail("edge_weight", edge_weight, ">= 0");
  if (!(min_contrast >= 0.0)) fail("min_contrast", min_contrast, ">= 0");
  if (!(fog_contrast >= 0.0)) fail("fog_contrast", fog_contrast, ">= 0");
}

int Skyline::VisibleCount() const {
  return static_cast<int>(std::count_if(y.begin(), y.end(), [](double v) { return std::isfinite(v); }));
}

Skyline ExtractSkyline(const cv::Mat& image, const SkylineOptions& options) {
  options.Check();
  if (image.empty() || image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4))
    throw InvalidArgument("skyline: the image must be a non-empty 8-bit grey, BGR or BGRA image");
  Skyline out;
  out.width = image.cols;
  out.height = image.rows;
  out.y.assign(image.cols, NAN);
  out.confidence.assign(image.cols, 0.0);
  if (image.rows < 8 || image.cols < 8) return out;

  const cv::Mat bgr = ToBgr(image);
  const LabConverter to_lab;

  // Search at a bounded width.
  const double scale = std::min(1.0, static_cast<double>(options.max_work_width_px) / image.cols);
  // Scratch images kept per thread: a video's frames reuse them instead of
  // faulting in ~10 MB of fresh pages per frame (a third of the time).
  thread_local Workspace ws;
  cv::Mat small;
  double sx = 1.0, sy = 1.0;  // work-image pixels per full-size pixel, across and down
  if (scale < 1.0) {
    // Area averaging by a whole factor first (OpenCV's fast path; its
    // general one took 30 ms for 4000 x 3000), then to the work size. The
    // whole-factor step drops the last < k rows and columns.
    int k = static_cast<int>(1.0 / scale);
    if (bgr.rows / k < 8) k = 1;  // a thin strip: straight to the work size
    cv::Mat source = bgr;
    if (k >= 2) {
      const cv::Mat crop = bgr(cv::Rect(0, 0, bgr.cols / k * k, bgr.rows / k * k));
      cv::resize(crop, ws.reduced, cv::Size(crop.cols / k, crop.rows / k), 0, 0, cv::INTER_AREA);
      source = ws.reduced;
    }
    if (source.cols <= options.max_work_width_px) {
      small = source;
    } else {
      const cv::Size work(options.max_work_width_px,
                          std::max(8, static_cast<int>(std::lround(source.rows * scale * k))));
      cv::resize(source, ws.small, work, 0, 0, cv::INTER_AREA);
      small = ws.small;
    }
    sx = static_cast<double>(small.cols) / (source.cols * k);  // source is the image reduced k times (k >= 1)
    sy = static_cast<double>(small.rows) / (source.rows * k);
  } else {
    small = bgr;
  }
  // One row per image column. Not blurred: the area reduction averages
  // already, and a 5 x 5 Gaussian changed no figure on the dev scenes, with or
  // without added pixel noise (measured), for 0.4 ms.
  const cv::Mat& work_t = ws.lab_t;
  cv::transpose(small, ws.small_t);  // 8-bit: a quarter of the bytes of a float transpose
  to_lab.Convert(ws.small_t, ws.lab_t);

  const double roll_rad = DegToRad(options.roll_hint_deg.value_or(0.0));
  const double slope = -std::tan(roll_rad);  // positive roll: the skyline rises to the right
  BoundarySteps(work_t, ws.steps);
  // Pass 1 only gives the first boundary that pass 2 learns the colours of
  // sky and ground from: at half the work size (a quarter of the time).
  std::vector<int> boundary(work_t.rows);
  {
    Halve(work_t, ws.lab_h);
    BoundarySteps(ws.lab_h, ws.steps_h);
    SkyScoreFromTopBand(ws.lab_h, ws.sky_h);
    EdgeAbovePenalty(ws.steps_h, ws.sky_h, ws.lab_h, ws.pen_h);
    const std::vector<int> half =
        SolveBoundary(ws.sky_h, ws.steps_h, ws.pen_h, options.smoothness, options.edge_weight, slope, ws.acc);
    for (int c = 0; c < work_t.rows; ++c)
      boundary[c] = std::min(work_t.cols, 2 * half[std::min(c / 2, static_cast<int>(half.size()) - 1)]);
  }
  SkyScoreFromHistograms(work_t, boundary, ws.sky);
  EdgeAbovePenalty(ws.steps, ws.sky, work_t, ws.pen);
  boundary = SolveBoundary(ws.sky, ws.steps, ws.pen, options.smoothness, options.edge_weight, slope, ws.acc);

  // No sky: the region above the boundary must look like sky somewhere.
  const int ww = work_t.rows, wh = work_t.cols;
  {
    double sky_px = 0;
    for (int c = 0; c < ww; ++c) sky_px += boundary[c];
    if (sky_px < 0.01 * ww * wh) return out;
  }

  // Refine each full-size column around the (interpolated) boundary.
  std::vector<ColumnFit> fits(image.cols);
  const int window = static_cast<int>(std::ceil(1.0 / sy)) + 2;
  for (int x = 0; x < image.cols; ++x) {
    const double wc = std::clamp((x + 0.5) * sx - 0.5, 0.0, ww - 1.0);
    const int c0 = static_cast<int>(wc), c1 = std::min(c0 + 1, ww - 1);
    const double f = wc - c0;
    const double yb = ((1 - f) * boundary[c0] + f * boundary[c1]) / sy;
    if (yb <= 1.0 || yb >= image.rows - 1.0) continue;  // no boundary inside the image
    fits[x] = RefineColumn(bgr, to_lab, x, yb, window);
  }
  const std::vector<uint8_t> occluded = FindOccluders(fits, image.rows);
  const int grow = std::max(3, image.cols / 128);  // the occluder's edges and the DP's way round it
  std::vector<uint8_t> grown(occluded);
  for (int x = 0; x < image.cols; ++x)
    if (occluded[x])
      for (int k = std::max(0, x - grow); k <= std::min(image.cols - 1, x + grow); ++k) grown[k] = 1;
  for (int x = 0; x < image.cols; ++x) {
    const ColumnFit& f = fits[x];
    if (!std::isfinite(f.y) || grown[x] || f.contrast < options.min_contrast) continue;
    out.y[x] = std::clamp(f.y, 0.0, static_cast<double>(image.rows));
    out.confidence[x] = std::clamp((f.contrast - options.min_contrast) / 20.0, 0.05, 1.0);
  }
  // Fog: where a horizon is seen against the sky, some of it stands out
  // clearly; when even the clearest tenth of the boundary is faint and the
  // boundary is soft, it is where near terrain fades into fog or whiteout,
  // not the horizon (a faint but sharp far ridge in haze stays).
  std::vector<double> contrasts, spreads;
  for (int x = 0; x < image.cols; ++x)
    if (std::isfinite(out.y[x])) contrasts.push_back(fits[x].contrast), spreads.push_back(fits[x].spread);
  if (!contrasts.empty()) {
    const double clearest = Quantile(contrasts, 0.9), median_spread = Quantile(spreads, 0.5);
    // A fade spreads its colour change over more rows than an edge, which
    // the renderer or the lens smooths over ~2 rows per 1000 columns.
    const double soft = kFogSpreadRows * std::max(1.0, image.cols / 1024.0);
    if (clearest < options.fog_contrast && median_spread > soft) {
      std::fill(out.y.begin(), out.y.end(), NAN);
      std::fill(out.confidence.begin(), out.confidence.end(), 0.0);
    }
  }
  return out;
}

cv::Mat DrawSkylineDebug(const cv::Mat& image, const Skyline& skyline) {
  cv::Mat canvas = image.channels() == 3 ? image.clone() : ToBgr(image);
  const int thick = std::max(1, image.cols / 600);
  for (int x = 0; x < skyline.width; ++x) {
    if (!std::isfinite(skyline.y[x])) {
      cv::line(canvas, {x, 0}, {x, std::max(4, image.rows / 60)}, cv::Scalar(255, 0, 255), 1);
      continue;
    }
    const double c = skyline.confidence[x];
    const cv::Scalar colour(0, 255 * c, 255 * (1 - c));  // red (low) to green (high)
    cv::circle(canvas, {x, static_cast<int>(std::lround(skyline.y[x]))}, thick, colour, cv::FILLED);
  }
  return canvas;
}

}  // namespace horizonreg
