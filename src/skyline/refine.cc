// SPDX-License-Identifier: MIT
#include "skyline/refine.h"

#include <algorithm>
#include <utility>

namespace horizonreg::skyline_detail {
namespace {

constexpr float kTopStepShare = 0.4f;  // refinement: the topmost step at least this share of the strongest wins
constexpr float kTopStepMin = 5.0f;    // ... and at least this delta E (noise in the sky stays below)
constexpr int kStepColumns = 2;        // refinement: steps read from the column averaged with 2 on each side
constexpr float kFaintContrast = 8.0f;  // delta E below which a boundary is read from the averaged columns
constexpr float kTreeGreen = 7.0f;     // -a* above which a dark boundary is a tree (dark shaded terrain is greyer)

// RaiseToSkyEnd (at 1024 columns; rows scale with the width).
constexpr int kSkyEndSearchRows = 20;  // how far above the boundary the sky's end is sought
constexpr int kSkyEndFitRows = 16;     // the rows above a candidate row fitted by a line
constexpr int kSkyEndMinRaise = 4;     // rows: a smaller raise is left to the crossing (3 leaves no texture rows)
constexpr float kSkyEndChromaWeight = 0.4f;  // JPEG blurs and blocks the chroma
constexpr float kSkyEndSigmas = 4.0f, kSkyEndMinDeltaE = 3.5f;
constexpr float kSkyEndUniform = 0.5f;      // the fitted rows' 90th-percentile residual, at most this share of the threshold
constexpr float kSkyEndHeldShare = 0.8f;    // share of the rows down to the boundary that depart
constexpr float kSkyEndTexture = 3.0f;      // their texture over the fitted rows' (floor 0.3 delta L)
constexpr int kSkyEndEdgeRows = 2;          // rows above the boundary left out of the texture (a sloping edge)
constexpr float kSkyEndTextureFloor = 0.3f;

// RaiseToFirstDeparture (at 1024 columns; rows scale with the width).
constexpr int kFirstDepartSearchRows = 6;      // how far above the boundary the first departure is sought
constexpr int kFirstDepartFitRows = 12;        // the sky's rows above the search, fitted by a line
constexpr int kFirstDepartGroundRows = 5;      // rows read below the boundary
constexpr float kFirstDepartShare = 0.3f;      // a departure of this share of the contrast is terrain's ...
constexpr float kFirstDepartMinDeltaL = 2.0f;  // ... and at least this (JPEG's blocks in a smooth sky stay below)
constexpr float kFirstDepartSigmas = 6.0f;     // ... and this many of the sky's robust sigmas
constexpr float kFirstDepartBluer = 2.0f;      // b*: a row this much bluer than the fitted sky is sky
constexpr double kFirstDepartMinRaise = 0.5;   // rows

// RaiseToSkyModelDeparture (at 1024 columns; rows scale with the width).
constexpr int kDepartSearchRows = 20;     // how far above the boundary the ridge's top is sought
constexpr int kDepartLineRows = 16;       // the rows above a candidate row fitted by a line
constexpr float kDepartSigmas = 4.0f;     // departure from the model and from the line, in model sigmas
constexpr float kDepartHeldShare = 0.8f;  // share of the rows down to the boundary that depart
constexpr int kDepartMinRaise = 3;        // rows
constexpr float kDepartAboveShare = 0.5f; // the sky above the top: its median departure at most this share of the ridge's
constexpr float kDepartGapShare = 0.5f;   // the ridge's departure falling below this share of its peak before the boundary ...
constexpr float kDepartUnderFactor = 2.0f; // ... over terrain departing this many times that peak: a band in the sky

// RaiseDips (at 1024 columns; rows scale with the width).
constexpr double kDipReach = 6;   // columns on each side whose boundary a column is compared with
constexpr double kDipRows = 2.5;  // a column this far below both sides' tops is a dip
constexpr int kDipSkyRows = 6;    // rows of sky fitted by a line, from kDipSkyAbove above the neighbours' top
constexpr int kDipSkyAbove = 8;
constexpr float kDipMinDeltaE = 3.0f;  // the least departure from the line that is terrain (JPEG's blocks stay below)
constexpr float kDipSigmas = 4.0f;
constexpr float kDipHeldShare = 0.8f;  // share of the rows down to the boundary that depart
constexpr int kDipPasses = 3;

}  // namespace

void AverageStrips(const cv::Mat& bgr, const std::vector<int>& first, int count, int half, std::vector<uint8_t>& out) {
  const int h = bgr.rows, w = bgr.cols;
  out.assign(3 * static_cast<size_t>(w) * count, 0);
  for (int x = 0; x < w; ++x) {
    if (first[x] == RefineStrips::kNoStrip) continue;
    const int c0 = std::max(0, x - half), c1 = std::min(w - 1, x + half), n = c1 - c0 + 1;
    uint8_t* strip = out.data() + 3 * static_cast<size_t>(x) * count;
    for (int i = 0; i < count; ++i) {
      const uint8_t* row = bgr.ptr<uint8_t>(std::clamp(first[x] + i, 0, h - 1));
      int sum[3] = {0, 0, 0};
      for (int c = c0; c <= c1; ++c)
        for (int k = 0; k < 3; ++k) sum[k] += row[3 * c + k];
      for (int k = 0; k < 3; ++k) strip[3 * i + k] = static_cast<uint8_t>((sum[k] + n / 2) / n);
    }
  }
}

void GatherStrips(const cv::Mat& bgr, RefineStrips& strips) {
  AverageStrips(bgr, strips.first, strips.count, 0, strips.column.bgr);
  AverageStrips(bgr, strips.first, strips.count, kStepColumns, strips.wide.bgr);
  strips.column.Convert();
  strips.wide.Convert();
}

ColumnFit RefineColumn(RefineStrips& strips, int x, int h, int centre, int window, float lightness_gain) {
  const LabStrips &lab = strips.column, &wide = strips.wide;
  const int first = strips.first[x] - x * strips.count;  // index = row - first
  // The topmost clear step in the window (the paper scans each column from
  // the top for the first edge): a faint far ridge above a contrasty near
  // one is the skyline.
  std::vector<float>& steps = strips.steps;
  std::vector<int>& rows = strips.rows;
  steps.clear(), rows.clear();
  int best = centre;
  float best_step = -1;
  for (int r = centre - window; r <= centre + window; ++r) {
    if (r < 1 || r >= h) continue;
    steps.push_back(std::sqrt(wide.DistanceSq(r - first, r - 1 - first)));
    rows.push_back(r);
    if (steps.back() > best_step) best_step = steps.back(), best = r;  // the strongest, if no step is clear
  }
  const int m = static_cast<int>(steps.size());
  for (int i = 0; i < m; ++i) {
    const bool local_max = (i == 0 || steps[i] >= steps[i - 1]) && (i + 1 == m || steps[i] >= steps[i + 1]);
    // Clear: at least kTopStepMin with the lightness difference times lightness_gain.
    if (local_max && steps[i] >= kTopStepShare * best_step &&
        std::sqrt(wide.DistanceSq(rows[i] - first, rows[i] - 1 - first, lightness_gain)) >= kTopStepMin) {
      best = rows[i];
      break;
    }
  }
  ColumnFit fit;
  if (best_step < 0) return fit;
  // The local sky and ground colours (3-row means 2-4 rows from the step)
  // and the half-way crossing, read from the column itself (a tree's edge
  // stays sharp) when the boundary is clear, from the column averaged with
  // its neighbours when it is faint (haze: a few delta E, which the pixel
  // noise of one column would scatter by several rows).
  auto read = [&](const LabStrips& src, ColumnFit& f) {
    float sky[3] = {0, 0, 0}, ground[3] = {0, 0, 0};
    for (int k = 2; k <= 4; ++k) {
      const int above = best - 1 - k - first, below = best + k - first;
      sky[0] += src.l[above], sky[1] += src.a[above], sky[2] += src.b[above];
      ground[0] += src.l[below], ground[1] += src.a[below], ground[2] += src.b[below];
    }
    for (int k = 0; k < 3; ++k) sky[k] *= 1.0f / 3, ground[k] *= 1.0f / 3;
    const float d[3] = {sky[0] - ground[0], sky[1] - ground[1], sky[2] - ground[2]};
    const float dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    f.contrast = std::sqrt(dd);
    f.spread = best_step > 0 ? f.contrast / best_step : 0;
    f.ground_l = ground[0];
    f.sky_chroma = std::sqrt(sky[1] * sky[1] + sky[2] * sky[2]);
    f.sky_l = sky[0];
    f.ground_green = -ground[1];
    if (dd < 1e-6f) return;
    const double y = ColourCrossing(src.l.data(), src.a.data(), src.b.data(), first, sky, ground, best - 2, best + 2);
    f.y = std::isfinite(y) ? y : best;
  };
  read(lab, fit);
  if (fit.contrast < kFaintContrast) {
    ColumnFit averaged;
    read(wide, averaged);
    fit = averaged;
  }
  return fit;
}

void RaiseToSkyEnd(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y) {
  const int h = bgr.rows, w = bgr.cols;
  const double scale = std::max(1.0, w / 1024.0);
  const int search = static_cast<int>(std::lround(kSkyEndSearchRows * scale));
  const int fit_rows = static_cast<int>(std::lround(kSkyEndFitRows * scale));
  const int count = search + fit_rows + 1;
  // Per column, three strips of `count` rows (the column and its two
  // neighbours) ending at its boundary row, converted in one batch.
  std::vector<int> first(w, RefineStrips::kNoStrip);
  for (int x = 0; x < w; ++x)
    if (std::isfinite(y[x]) && !skip[x] && std::floor(y[x]) - kSkyEndMinRaise >= fit_rows)
      first[x] = static_cast<int>(std::floor(y[x])) - search - fit_rows;
  LabStrips lab;
  lab.bgr.assign(9 * static_cast<size_t>(w) * count, 0);
  for (int x = 0; x < w; ++x) {
    if (first[x] == RefineStrips::kNoStrip) continue;
    for (int k = 0; k < 3; ++k) {
      const int c = std::clamp(x + k - 1, 0, w - 1);
      uint8_t* out = lab.bgr.data() + 3 * (static_cast<size_t>(3 * x + k) * count);
      for (int i = 0; i < count; ++i) {
        const uint8_t* px = bgr.ptr<uint8_t>(std::clamp(first[x] + i, 0, h - 1)) + 3 * c;
        std::copy(px, px + 3, out + 3 * i);
      }
    }
  }
  lab.Convert();
  std::vector<float> res(fit_rows), sorted(fit_rows), tex(count), curl(count);
  for (int x = 0; x < w; ++x) {
    if (first[x] == RefineStrips::kNoStrip) continue;
    const size_t own = static_cast<size_t>(3 * x + 1) * count, left = own - count, right = own + count;
    const float* l = lab.l.data() + own;
    const float* a = lab.a.data() + own;
    const float* b = lab.b.data() + own;
    // Texture: the lightness difference between the neighbouring columns
    // (rock and snow) and its second difference (a cloud's smooth
    // gradient has one but not the other).
    for (int i = 0; i < count; ++i) {
      const float lr = lab.l[right + i], ll = lab.l[left + i];
      tex[i] = 0.5f * std::abs(lr - ll), curl[i] = std::abs(lr - 2.0f * l[i] + ll);
    }
    const int yi = static_cast<int>(std::floor(y[x])) - first[x];  // the boundary row, strip index
    for (int r = std::max(fit_rows, static_cast<int>(std::floor(y[x])) - search) - first[x]; r <= yi - kSkyEndMinRaise;
         ++r) {
      // Least-squares line through rows r - fit_rows .. r - 1, per channel,
      // in t = row - r (mean t = -(n + 1) / 2).
      const int n = fit_rows;
      const double tm = -(n + 1) / 2.0;
      double stt = 0, mean[3] = {0, 0, 0}, st[3] = {0, 0, 0};
      for (int i = r - n; i < r; ++i) {
        const double t = (i - r) - tm;
        const double v[3] = {l[i], kSkyEndChromaWeight * a[i], kSkyEndChromaWeight * b[i]};
        stt += t * t;
        for (int k = 0; k < 3; ++k) mean[k] += v[k], st[k] += t * v[k];
      }
      double slope[3];
      for (int k = 0; k < 3; ++k) mean[k] /= n, slope[k] = st[k] / stt;
      auto departure = [&](int i) {
        const double t = (i - r) - tm;
        const double d0 = l[i] - (mean[0] + slope[0] * t), d1 = kSkyEndChromaWeight * a[i] - (mean[1] + slope[1] * t),
                     d2 = kSkyEndChromaWeight * b[i] - (mean[2] + slope[2] * t);
        return static_cast<float>(std::sqrt(d0 * d0 + d1 * d1 + d2 * d2));
      };
      for (int i = 0; i < n; ++i) res[i] = departure(r - n + i);
      sorted = res;
      std::sort(sorted.begin(), sorted.end());
      const float median = 0.5f * (sorted[(n - 1) / 2] + sorted[n / 2]);
      const float q = 0.9f * (n - 1);
      const int q0 = static_cast<int>(q);
      const float p90 = sorted[q0] + (q - q0) * (sorted[std::min(n - 1, q0 + 1)] - sorted[q0]);
      const float threshold = std::max(kSkyEndSigmas * (1.48f * median + 0.2f), kSkyEndMinDeltaE);
      if (p90 > kSkyEndUniform * threshold) continue;
      int held = 0;
      for (int i = r; i < yi; ++i) held += departure(i) > threshold;
      if (!(departure(r) > threshold && departure(r + 1) > threshold) || held < kSkyEndHeldShare * (yi - r)) continue;
      auto textured = [&](const std::vector<float>& t) {
        float below = 0, above = 0;
        const int end = yi - kSkyEndEdgeRows;
        for (int i = r + 1; i < end; ++i) below += t[i];
        for (int i = r - n; i < r; ++i) above += t[i];
        below /= std::max(1, end - r - 1), above /= n;
        return below > kSkyEndTexture * std::max(above, kSkyEndTextureFloor);
      };
      if (textured(tex) && textured(curl)) y[x] = first[x] + r - 0.5;
      break;
    }
  }
}

void RaiseToFirstDeparture(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y) {
  const int h = bgr.rows, w = bgr.cols;
  const double scale = std::max(1.0, w / 1024.0);
  const int search = static_cast<int>(std::lround(kFirstDepartSearchRows * scale));
  const int n = static_cast<int>(std::lround(kFirstDepartFitRows * scale));
  const int count = n + search + kFirstDepartGroundRows + 1;
  std::vector<int> first(w, RefineStrips::kNoStrip);
  for (int x = 0; x < w; ++x)
    if (std::isfinite(y[x]) && !skip[x] && std::floor(y[x]) - search - n >= 0 &&
        std::floor(y[x]) + kFirstDepartGroundRows < h)
      first[x] = static_cast<int>(std::floor(y[x])) - search - n;
  LabStrips lab;
  AverageStrips(bgr, first, count, 1, lab.bgr);
  lab.Convert();
  std::vector<float> dep(count), res(n);
  for (int x = 0; x < w; ++x) {
    if (first[x] == RefineStrips::kNoStrip) continue;
    const size_t base = static_cast<size_t>(x) * count;
    const float* l = lab.l.data() + base;
    const float* b = lab.b.data() + base;
    const int yi = static_cast<int>(std::floor(y[x])) - first[x];  // the boundary row, strip index
    const int r0 = yi - search;                                   // the first row searched; the sky's rows above it
    // The sky: least-squares lines in L* and b* through the n rows above the search.
    const double tm = r0 - (n + 1) / 2.0;
    double stt = 0, ml = 0, mb = 0, stl = 0, stb = 0;
    for (int j = r0 - n; j < r0; ++j) {
      const double t = j - tm;
      stt += t * t, ml += l[j], mb += b[j], stl += t * l[j], stb += t * b[j];
    }
    ml /= n, mb /= n;
    const double sl = stl / stt, sb = stb / stt;
    auto dl = [&](int j) { return static_cast<float>(l[j] - (ml + sl * (j - tm))); };
    auto db = [&](int j) { return static_cast<float>(b[j] - (mb + sb * (j - tm))); };
    for (int j = r0 - n; j < r0; ++j) res[j - (r0 - n)] = std::abs(dl(j));
    std::nth_element(res.begin(), res.begin() + n / 2, res.end());
    const float sigma = 1.48f * res[n / 2];
    // A row bluer than that sky is sky (a band of blue sky under a cloud
    // the lines were fitted to): the lines are not the sky next to the boundary.
    bool bluer = false;
    for (int j = r0; j <= yi; ++j) bluer = bluer || db(j) < -kFirstDepartBluer;
    if (bluer) continue;
    // The contrast: the ground's departure (rows 2-4 below the boundary), or
    // a band's on the way down (snow whiter than the sky over darker rock).
    float ground = 0;
    for (int j = yi + 2; j <= yi + 4; ++j) ground += dl(j) / 3;
    float contrast = std::abs(ground);
    for (int j = r0; j <= yi; ++j) dep[j] = std::abs(dl(j)), contrast = std::max(contrast, dep[j]);
    const float threshold = std::max({kFirstDepartShare * contrast, kFirstDepartMinDeltaL, kFirstDepartSigmas * sigma});
    // The topmost row from which every row down to the boundary departs.
    int top = -1;
    // A dark crest over brighter ground: the boundary's own row, half way
    // between them, can match the sky's lightness; the chain starts above it.
    // (Not a bright band over darker ground: a rendered sky's glow at the
    // horizon reads so, fuji_04 98.4% -> 93.7%.)
    const int start = dep[yi] <= threshold && ground > 0 && dl(yi - 1) < 0 ? yi - 1 : yi;
    for (int j = start; j >= r0 && dep[j] > threshold; --j) top = j;
    if (top <= r0) continue;  // none, or the whole search departs (the lines are not the sky's)
    // Where the departure crosses the threshold, rows read at their centres (row j at j + 0.5).
    const double raised = first[x] + (top - 1) + 0.5 + (threshold - dep[top - 1]) / std::max(1e-6f, dep[top] - dep[top - 1]);
    if (raised < y[x] - kFirstDepartMinRaise) y[x] = raised;
  }
}

void RaiseToSkyModelDeparture(const cv::Mat& bgr, const SkyModel& model, double work_per_px_x, double work_per_px_y,
                              float deep_blue_b, const std::vector<uint8_t>& skip, std::vector<double>& y,
                              std::vector<double>& alt) {
  const int h = bgr.rows, w = bgr.cols;
  alt.assign(w, NAN);
  if (!model.fitted()) return;
  const double scale = std::max(1.0, w / 1024.0);
  const int search = static_cast<int>(std::lround(kDepartSearchRows * scale));
  const int line = static_cast<int>(std::lround(kDepartLineRows * scale));
  const double min_raise = kDepartMinRaise * scale;
  // Per column, `count` rows of the column averaged with its neighbours,
  // from `line` + 3 rows above the search to 2 rows below the boundary row.
  const int count = search + line + 5;
  std::vector<int> first(w, RefineStrips::kNoStrip);
  for (int x = 0; x < w; ++x) {
    if (!std::isfinite(y[x]) || skip[x]) continue;
    const int yb = static_cast<int>(std::floor(y[x]));
    if (yb - search - line - 3 >= 0 && yb + 2 <= h && y[x] - min_raise > 0) first[x] = yb - search - line - 3;
  }
  LabStrips lab;
  AverageStrips(bgr, first, count, 1, lab.bgr);
  lab.Convert();
  const float inv = 1.0f / model.scale();
  std::vector<float> pred(3 * static_cast<size_t>(count));
  std::vector<uint8_t> departs(count);
  std::vector<float> dist(count), sorted;
  for (int x = 0; x < w; ++x) {
    if (first[x] == RefineStrips::kNoStrip) continue;
    const size_t base = static_cast<size_t>(x) * count;
    const float* l = lab.l.data() + base;
    const float* a = lab.a.data() + base;
    const float* b = lab.b.data() + base;
    const int yb = static_cast<int>(std::floor(y[x])) - first[x];  // the boundary row, strip index
    const int top = yb - search;
    const double wc = (x + 0.5) * work_per_px_x - 0.5;
    const int below_end = std::min(count, yb + 2);
    for (int i = top; i < below_end; ++i) {
      model.Predict(wc, (first[x] + i + 0.5) * work_per_px_y - 0.5, &pred[3 * i]);
      const float dl = l[i] - pred[3 * i], da = a[i] - pred[3 * i + 1], db = b[i] - pred[3 * i + 2];
      dist[i] = std::sqrt(dl * dl + da * da + db * db) * inv;
      departs[i] = dist[i] > kDepartSigmas && b[i] > deep_blue_b;
    }
    // Whether rows i and i + 1 depart from the line through the `line` rows above i.
    auto off_line = [&](int i) {
      double sum_t = 0, sum_tt = 0, sum_v[3] = {0, 0, 0}, sum_tv[3] = {0, 0, 0};
      for (int j = i - line; j < i; ++j) {
        const double t = j - i, v[3] = {l[j], a[j], b[j]};
        sum_t += t, sum_tt += t * t;
        for (int k = 0; k < 3; ++k) sum_v[k] += v[k], sum_tv[k] += t * v[k];
      }
      const double det = line * sum_tt - sum_t * sum_t;
      double at0[3], slope[3];
      for (int k = 0; k < 3; ++k) {
        slope[k] = (line * sum_tv[k] - sum_t * sum_v[k]) / det;
        at0[k] = (sum_v[k] - slope[k] * sum_t) / line;
      }
      for (int d = 0; d <= 1; ++d) {
        const double v[3] = {l[i + d], a[i + d], b[i + d]};
        double dd = 0;
        for (int k = 0; k < 3; ++k) dd += (v[k] - at0[k] - d * slope[k]) * (v[k] - at0[k] - d * slope[k]);
        if (!(std::sqrt(dd) * inv > kDepartSigmas)) return false;
      }
      return true;
    };
    for (int i = top; i + 1 < yb; ++i) {
      if (!departs[i] || !departs[i + 1]) continue;
      int held = 0;
      for (int j = i; j < yb; ++j) held += departs[j];
      if (held < kDepartHeldShare * (yb - i) || !off_line(i)) continue;
      // The sky above the top must be the model's: where the model does not
      // fit it (a sunset's glow, AKJNC_20121001), departing from the model
      // tells nothing (measured: 30 of the real photos' 100 columns raised
      // off their traced horizon, none of those raised onto it).
      if (i - 1 > top) {
        auto median = [&](int from, int to) {
          sorted.assign(dist.begin() + from, dist.begin() + to);
          std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
          return sorted[sorted.size() / 2];
        };
        if (median(top, i - 1) > kDepartAboveShare * median(i, yb)) break;
      }
      // Sky between the band and much more contrasty terrain under it: the
      // band's departure falls back towards the sky's before the boundary,
      // so it is a ring of glow or haze in the sky, not a ridge (terrain
      // reaches down to the next edge). Measured: 16 of the real photos' 100
      // columns raised off their traced horizon, 2 of 317 raised onto it.
      {
        const int peak = static_cast<int>(std::max_element(dist.begin() + i, dist.begin() + yb) - dist.begin());
        const float low = *std::min_element(dist.begin() + peak, dist.begin() + yb);
        const float under = *std::max_element(dist.begin() + yb, dist.begin() + below_end);
        if (low < kDepartGapShare * dist[peak] && under >= kDepartUnderFactor * dist[peak]) break;
      }
      // The half-way crossing from the model's sky to the ridge's colour.
      const int g1 = std::min(yb, i + 4);
      float ground[3] = {0, 0, 0};
      for (int j = i + 1; j < g1; ++j) ground[0] += l[j], ground[1] += a[j], ground[2] += b[j];
      for (float& g : ground) g /= static_cast<float>(g1 - i - 1);
      const double c = ColourCrossing(l, a, b, 0, &pred[3 * i], ground, i - 2, i + 2);
      const double ny = (std::isfinite(c) ? c : i - 0.5) + first[x];
      if (y[x] - ny >= min_raise) alt[x] = y[x], y[x] = ny;
      break;
    }
  }
}

void ContinueFaintColumns(const std::vector<ColumnFit>& fits, const std::vector<uint8_t>& skip, double faint_contrast,
                          double max_jump_px, int image_rows, Skyline& out) {
  const int w = static_cast<int>(fits.size());
  auto join = [&](int x, int from) {
    const ColumnFit& f = fits[x];
    if (std::isfinite(out.y[x]) || !std::isfinite(f.y) || skip[x] || f.contrast < faint_contrast) return;
    const double y = std::clamp(f.y, 0.0, static_cast<double>(image_rows));
    if (!(std::abs(y - out.y[from]) <= max_jump_px)) return;
    out.y[x] = y;
    out.confidence[x] = 0.05;
  };
  for (int x = 1; x < w; ++x)
    if (std::isfinite(out.y[x - 1])) join(x, x - 1);
  for (int x = w - 2; x >= 0; --x)
    if (std::isfinite(out.y[x + 1])) join(x, x + 1);
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
  // A dip's side: the boundary fell onto an inner edge for a stretch and
  // comes back to a level it held within max_width on the other side (to
  // within half a flank's rise). A spike cut by the image's edge stands
  // above all that lies beside it; measured: a copy of AKJNC_20120605 a
  // third of a stop darker dipped 15 px for 20 columns 95 columns from its
  // right edge, and its snow ridge's last 100 columns were nulled as a tree.
  auto dip_side = [&](int x, int sense) {  // sense -1: a rising flank at x (the level after it, to its right)
    const double level = y_at(x - 3 * sense);
    const int lo = sense == -1 ? std::max(0, x - max_width) : x + 3;
    const int hi = sense == -1 ? x - 3 : std::min(w, x + max_width);
    for (int k = lo; k < hi; ++k)
      if (fits[k].y <= level + 0.5 * min_rise) return true;
    return false;
  };
  for (int x = 0; x < w; ++x) {
    if (flank[x] != -1) continue;
    // A rising flank, then a falling one within max_width (or the image edge).
    int end = -1;
    for (int k = x + 1; k < std::min(w, x + max_width); ++k)
      if (flank[k] == 1) end = k;
    if (end < 0 && w - x < max_width && !dip_side(x, -1)) end = w - 1;
    if (end >= 0) std::fill(occluded.begin() + x, occluded.begin() + end + 1, uint8_t{1});
  }
  for (int x = w - 1; x >= 0; --x)  // a falling flank near the left edge
    if (flank[x] == 1 && x < max_width &&
        std::none_of(flank.begin(), flank.begin() + x, [](int f) { return f == -1; }) && !dip_side(x, 1))
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

double NoiseSigma(const cv::Mat& bgr) {
  if (bgr.type() != CV_8UC3 || bgr.rows < 3 || bgr.cols < 3) return 0.0;
  const int w = bgr.cols;
  std::vector<int> luma(3 * static_cast<size_t>(w));
  auto fill = [&](int r, int* out) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(r);
    for (int c = 0; c < w; ++c) out[c] = 29 * p[c][0] + 150 * p[c][1] + 77 * p[c][2];  // luma * 256
  };
  // |convolution| / 256 in whole luma units: at most 36 * 255.
  std::vector<int> hist(36 * 255 + 1, 0);
  long n = 0;
  // Rows r - 1, r, r + 1 in a, b, c; the next triple's first row is this
  // one's last, so only two rows are converted per step.
  int* a = luma.data();
  int* b = a + w;
  int* c = b + w;
  fill(0, a);
  for (int r = 1; r + 1 < bgr.rows; r += 2) {
    fill(r, b), fill(r + 1, c);
    for (int x = 1; x + 1 < w; ++x) {
      const int v =
          (a[x - 1] - 2 * a[x] + a[x + 1]) - 2 * (b[x - 1] - 2 * b[x] + b[x + 1]) + (c[x - 1] - 2 * c[x] + c[x + 1]);
      ++hist[std::min(36 * 255, (std::abs(v) + 128) >> 8)];
      ++n;
    }
    std::swap(a, c);
  }
  if (n == 0) return 0.0;
  // The median, interpolated within its bin (the values are whole numbers).
  long below = 0;
  for (size_t k = 0; k < hist.size(); ++k) {
    if (below + hist[k] >= (n + 1) / 2) {
      const double within = hist[k] ? (0.5 * n - below) / hist[k] : 0.5;
      return std::max(0.0, k - 0.5 + within) / (0.6745 * 6.0);
    }
    below += hist[k];
  }
  return 0.0;
}

std::vector<uint8_t> GridRunColumns(const std::vector<double>& y, int grid, double slack, int min_run) {
  const int w = static_cast<int>(y.size());
  std::vector<uint8_t> out(w, 0);
  auto row_of = [&](int x) -> long {  // the grid row y[x] lies on, or -1
    if (!std::isfinite(y[x])) return -1;
    const long k = std::lround(y[x] / grid);
    return std::abs(y[x] - static_cast<double>(k) * grid) <= slack ? k : -1;
  };
  for (int x = 0; x < w;) {
    const long k = row_of(x);
    int end = x + 1;
    while (k >= 0 && end < w && row_of(end) == k) ++end;
    if (k >= 0 && end - x >= min_run) std::fill(out.begin() + x, out.begin() + end, 1);
    x = end;
  }
  return out;
}

std::vector<uint8_t> IsolatedRunColumns(const std::vector<double>& y, int max_run, int min_gap) {
  const int w = static_cast<int>(y.size());
  std::vector<uint8_t> out(w, 0);
  // Stretches: finite runs joined across gaps shorter than min_gap.
  std::vector<std::pair<int, int>> stretches;  // [first, end)
  for (int x = 0; x < w;) {
    if (!std::isfinite(y[x])) {
      ++x;
      continue;
    }
    int end = x;
    while (end < w && std::isfinite(y[end])) ++end;
    if (!stretches.empty() && x - stretches.back().second < min_gap)
      stretches.back().second = end;
    else
      stretches.emplace_back(x, end);
    x = end;
  }
  // Nulls out to an edge count as a gap; a stretch at an edge is never isolated.
  for (const auto& [first, end] : stretches)
    if (end - first <= max_run && first > 0 && end < w)
      for (int x = first; x < end; ++x) out[x] = std::isfinite(y[x]) ? 1 : 0;
  return out;
}

double Quantile(std::vector<double>& v, double q) {
  const auto it = v.begin() + std::min(v.size() - 1, static_cast<size_t>(q * v.size()));
  std::nth_element(v.begin(), it, v.end());
  return *it;
}

namespace {

// Where column x's own ridge starts, from strip row `top` to `bottom`
// (see RaiseDips): the half-way crossing, NaN if there is none.
double DipRidge(const cv::Mat& bgr, int x, int top, int bottom, std::vector<uint8_t>& strip, std::vector<float>& l,
                std::vector<float>& a, std::vector<float>& b) {
  const int n = bottom - top + 1, fit = kDipSkyRows;
  if (n < fit + 6) return NAN;
  strip.resize(3 * static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) std::copy_n(bgr.ptr<uint8_t>(top + i) + 3 * x, 3, strip.data() + 3 * i);
  l.resize(n), a.resize(n), b.resize(n);
  LabConverter::Instance().Convert(strip.data(), 3, n, l.data(), a.data(), b.data());
  // Least-squares line through the first `fit` rows, per channel, in
  // t = i - tm (mean 0).
  const double tm = (fit - 1) / 2.0;
  double mean[3] = {0, 0, 0}, slope[3] = {0, 0, 0}, stt = 0;
  for (int i = 0; i < fit; ++i) {
    const double v[3] = {l[i], a[i], b[i]};
    stt += (i - tm) * (i - tm);
    for (int k = 0; k < 3; ++k) mean[k] += v[k] / fit, slope[k] += (i - tm) * v[k];
  }
  for (double& s : slope) s /= stt;
  auto line = [&](int i, int k) { return mean[k] + slope[k] * (i - tm); };
  auto departure = [&](int i) {
    const double dl = l[i] - line(i, 0), da = a[i] - line(i, 1), db = b[i] - line(i, 2);
    return static_cast<float>(std::sqrt(dl * dl + da * da + db * db));
  };
  std::vector<float> res(fit);
  for (int i = 0; i < fit; ++i) res[i] = departure(i);
  std::nth_element(res.begin(), res.begin() + fit / 2, res.end());
  const float threshold = std::max(kDipMinDeltaE, kDipSigmas * 1.48f * res[fit / 2]);
  int found = -1;
  for (int i = fit; i + 2 < n; ++i)
    if (departure(i) > threshold && departure(i + 1) > threshold && departure(i + 2) > threshold) {
      found = i;
      break;
    }
  if (found < 0 || found + 3 >= n) return NAN;
  int held = 0;
  for (int i = found; i < n; ++i) held += departure(i) > threshold;
  if (held < kDipHeldShare * (n - found)) return NAN;
  float ground[3] = {0, 0, 0};
  for (int i = found; i < found + 3; ++i) ground[0] += l[i] / 3, ground[1] += a[i] / 3, ground[2] += b[i] / 3;
  float sky[3];
  for (int k = 0; k < 3; ++k) sky[k] = static_cast<float>(line(found - 1, k));
  const double c = ColourCrossing(l.data(), a.data(), b.data(), 0, sky, ground, found - 1, found + 1);
  return top + (std::isfinite(c) ? c : found - 0.5);
}

}  // namespace

void RaiseDips(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y, std::vector<double>& alt) {
  const int h = bgr.rows, w = bgr.cols;
  if (alt.empty()) alt.assign(w, NAN);
  // The columns raised before (finite alt), not read as neighbours.
  std::vector<uint8_t> raised(w);
  for (int x = 0; x < w; ++x) raised[x] = std::isfinite(alt[x]) ? 1 : 0;
  const int reach = ColumnsPer1024(kDipReach, w, 3);
  const double rows = kDipRows * std::max(1.0, w / 1024.0);
  std::vector<uint8_t> strip;
  std::vector<float> l, a, b;
  for (int pass = 0; pass < kDipPasses; ++pass) {
    const std::vector<double> y0 = y;
    int moved = 0;
    for (int x = reach; x + reach < w; ++x) {
      if (skip[x] || !std::isfinite(y0[x])) continue;
      // Each side's top, of its columns not raised before and of all.
      double left = INFINITY, right = INFINITY, left_all = INFINITY, right_all = INFINITY;
      for (int k = 1; k <= reach; ++k) {
        if (std::isfinite(y0[x - k])) {
          left_all = std::min(left_all, y0[x - k]);
          if (!raised[x - k]) left = std::min(left, y0[x - k]);
        }
        if (std::isfinite(y0[x + k])) {
          right_all = std::min(right_all, y0[x + k]);
          if (!raised[x + k]) right = std::min(right, y0[x + k]);
        }
      }
      // The lower of the two sides' tops, one side at least read from
      // columns not raised before.
      const double top = std::min(std::max(left, right_all), std::max(left_all, right));
      if (!std::isfinite(top) || y0[x] <= top + rows) continue;
      const int first = static_cast<int>(std::floor(top)) - kDipSkyAbove,
                last = static_cast<int>(std::floor(y0[x])) - 2;
      if (first < 0 || last >= h) continue;
      const double ny = DipRidge(bgr, x, first, last, strip, l, a, b);
      if (!std::isfinite(ny) || ny < top - 2.0) continue;
      if (!std::isfinite(alt[x])) alt[x] = y0[x];
      y[x] = ny;
      ++moved;
    }
    if (moved == 0) break;
  }
}

}  // namespace horizonreg::skyline_detail
