// SPDX-License-Identifier: MIT
#include "skyline/skyline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <vector>

#include "skyline/lab.h"
#include "skyline/refine.h"
#include "skyline/sky_model.h"
#include "skyline/vignetting.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

using skyline_detail::ColumnFit;
using skyline_detail::FindOccluders;
using skyline_detail::GatherStrips;
using skyline_detail::Quantile;
using skyline_detail::RefineColumn;
using skyline_detail::RefineStrips;
using skyline_detail::SkyModel;

constexpr double kNoisySigma = 3.0;     // luma noise (of 255) from which the photo is denoised (Denoised) ...
constexpr int kDenoiseDiameter = 5;     // ... by a bilateral filter this wide (px) ...
constexpr double kDenoiseColour = 7.0;  // ... averaging colours within this many noise sigmas ...
constexpr double kDenoiseSpace = 2.0;   // ... weighted by a Gaussian of this sigma (px)

constexpr int kHistBins = 16;             // per CIELAB axis
constexpr float kColourWeight = 0.25f;    // DP cost per misclassified pixel (edges weigh 1 per delta E)
constexpr float kEdgeAboveWeight = 0.5f;  // DP cost per delta E of sharp steps left above the boundary
constexpr float kEdgeNoise = 4.0f;        // delta E of a step that is still noise or a soft cloud edge
constexpr float kEdgeCap = 12.0f;         // delta E above which a step counts as fully an edge
constexpr float kSnowEdgeBoost = 4.0f;    // extra weight of a sharp step into white (snow) left above the boundary
constexpr float kDeepBlueB = -25.0f;      // b* below which a pixel is saturated blue: sky, never terrain ...
constexpr float kNormalCastB = -15.0f;    // ... lowered by the image's blue cast beyond this (median b* of its bottom third)
constexpr int kPersistentRows = 4;            // rows averaged on each side of a persistent step
constexpr float kTopmostMinStep = 1.0f;       // delta E: a persistent step is clear from this ...
constexpr float kTopmostNoiseFactor = 5.0f;   // ... or from this many times the sky's noise
constexpr float kTopmostAboveWeight = 2.0f;   // cost per delta E of clear steps left above the first boundary
constexpr double kFaintMaxJumpPx = 3.0;  // hysteresis: a faint column's largest step from its clear neighbour (per 1024 columns)
constexpr float kSkyModelVeto = 3.0f;         // sky-model deviation (robust sigmas) from which a pixel is not sky ...
constexpr float kSkyModelClean = 2.0f;        // sky-model deviation (robust sigmas) below which a pixel is clean sky
constexpr float kSubtleDeltaE = 12.0f;        // ... up to this colour distance (beyond: the histograms decide)
constexpr double kFloatReach = 0.25;     // FindFloatingClouds: share of the width on either side whose lowest first
                                         // boundary the sky under a cloud must lie above ...
constexpr double kFloatSkyRows = 1.0 / 60;  // ... share of the height that sky run spans at least ...
constexpr float kFloatRunSigmas = 10.0f;    // ... its largest departure from the sky model (robust sigmas) ...
constexpr float kFloatPeakSigmas = 9.0f;    // ... and the cloud's least peak departure over the model (lighter) ...
constexpr double kFloatMinColumns = 0.01;  // ... and its least width (share of the width)
constexpr float kSkyModelFloor = 1.0f;        // delta E: the sky model's least robust scale (rendered skies have no noise) ...
constexpr float kBlockSkyFloor = 2.0f;        // ... and where the skyline ran along JPEG's 8-row grid (GridRunColumns)
constexpr int kJpegBlockRows = 8;
constexpr double kGridRunColumns = 80.0;      // columns per 1024 (at least 40) of a run along one grid row ...
constexpr double kGridShortRunColumns = 16.0;  // ... and, once there is one, of the other runs read again (at least 12)
constexpr double kGridRowSlack = 0.75;        // rows: how near a grid row a boundary on it lies
constexpr double kIsolatedRunColumns = 16.0;  // per 1024 columns (at least 8): a stretch at most this long ...
constexpr double kIsolatedGapColumns = 8.0;   // ... between at least this many nulls each side (at least 5) is noise
constexpr double kExposureTarget = 0.42;  // linear light of the bright end (99.5th percentile of luma) ...
constexpr double kMaxExposureGain = 8.0;  // ... a photo under half of it is brightened to, by at most this (3 stops)
constexpr double kVignettedCornerStops = -1.0;  // a photo whose corners lose more light than this is flattened
constexpr double kLightnessSpanLow = 0.005;     // the photo's lightness span: from this quantile of L* ...
constexpr double kLightnessSpanHigh = 0.995;    // ... to this one (the work image, every 4th pixel across and down)
constexpr double kMaxLightnessStretch = 3.0;    // the refinement judges steps over the span as over 100, at most x3
constexpr double kFogReferenceLightness = 100.0;  // L* + 16 of a sky (L* 84) at which fog_contrast applies as it is
constexpr double kFogSpreadRows = 2.4;  // median contrast / largest one-row step above which a faint boundary is a fade
constexpr double kMonochromeSoftFactor = 1.5;  // ... times this in a monochrome image (no sky chroma to tell fog by)
constexpr double kFogRampNearRows = 4.0;       // rows under the boundary (per 1024 columns) where terrain meets fog ...
constexpr double kFogRampFarRows = 32.0;       // ... and where nearer terrain has come out of it
constexpr double kFogRampShare = 0.35;  // a fade is fog when its colour departs this share of fog_contrast more there
constexpr float kMonochromeChroma = 2.0f;  // chroma (delta E) that 99% of a monochrome image's pixels stay below

// How surely b* marks saturated blue (sky, never terrain) below the
// threshold deep_blue_b (DeepBlueB): 0 to 1 over a few units of b*.
inline float DeepBlue(float b, float deep_blue_b) { return Logistic((deep_blue_b - b) * (1.0f / 3)); }

// Saturated blue is sky only while it is not much darker than the sky
// above it: shadowed or hazy blue mountains under a clipped-white or
// cool-cast sky are as saturated as a deep sky (measured on copies of
// AK10_20090827: a shaded slope at L* 38, b* -32 under a white sky at L* 95;
// far ridges at L* 41, b* -30 under a sky at L* 66, b* -20). A deep blue
// sky below a white cloud keeps at least half the cloud's lightness (the
// rendered fuji_02 sits at 0.68 of it, so the ratio stays 0.5 against a
// non-blue reference); below a blue sky the sky darkens far less toward the
// horizon, so there the ratio is 0.7. 1 when l is above ratio * above_l,
// falling to 0 over a few units of L*; the ratio moves between the two over
// a few units of the reference's b* around -12.
constexpr float kDeepBlueDarkRatio = 0.5f;      // below a cloud or a pale sky
constexpr float kDeepBlueDarkRatioBlue = 0.7f;  // below a blue sky
inline float NotTooDark(float l, float above_l, float above_b) {
  const float ratio =
      kDeepBlueDarkRatio + Logistic((-12.0f - above_b) * 0.5f) * (kDeepBlueDarkRatioBlue - kDeepBlueDarkRatio);
  return Logistic((l - ratio * above_l) * (1.0f / 3));
}
inline int HistIndex(float l, float a, float b) {
  const int li = std::clamp(static_cast<int>(l * (kHistBins / 100.0f)), 0, kHistBins - 1);
  const int ai = std::clamp(static_cast<int>((a + 64.0f) * (kHistBins / 128.0f)), 0, kHistBins - 1);
  const int bi = std::clamp(static_cast<int>((b + 64.0f) * (kHistBins / 128.0f)), 0, kHistBins - 1);
  return (li * kHistBins + ai) * kHistBins + bi;
}

// The mean of each 2 x 2 block of a float plane (a half-size plane; an odd
// last row or column averages what it has). cv::resize spends several times
// as long on this.
HR_VECTOR_CLONES void HalvePlane(const cv::Mat& m, cv::Mat& out) {
  const int rows = (m.rows + 1) / 2, cols = (m.cols + 1) / 2, pairs = m.cols / 2;
  out.create(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r) {
    const float* a = m.ptr<float>(2 * r);
    const float* b = m.ptr<float>(std::min(2 * r + 1, m.rows - 1));
    float* o = out.ptr<float>(r);
    for (int c = 0; c < pairs; ++c) o[c] = 0.25f * (a[2 * c] + a[2 * c + 1] + b[2 * c] + b[2 * c + 1]);
    if (cols > pairs) o[pairs] = 0.25f * (a[m.cols - 1] + a[m.cols - 1] + b[m.cols - 1] + b[m.cols - 1]);
  }
}

void Halve(const LabPlanes& lab, LabPlanes& out) {
  HalvePlane(lab.l, out.l);
  HalvePlane(lab.a, out.a);
  HalvePlane(lab.b, out.b);
}

// Pass 1: sky likeness relative to the image's top band (assumed sky).
// Planes transposed (one row per image column).
HR_VECTOR_CLONES float SkyScoreFromTopBand(const LabPlanes& lab, float deep_blue_b, cv::Mat& s) {
  const int w = lab.Rows(), h = lab.Cols();
  const int band = std::max(2, h / 30);
  std::vector<float> ls;
  ls.reserve(static_cast<size_t>(w) * band);
  auto band_median = [&](const cv::Mat& plane) {  // the top band's median of one plane
    ls.clear();
    for (int c = 0; c < w; ++c) ls.insert(ls.end(), plane.ptr<float>(c), plane.ptr<float>(c) + band);
    std::nth_element(ls.begin(), ls.begin() + ls.size() / 2, ls.end());
    return ls[ls.size() / 2];
  };
  const float lm = band_median(lab.l), bm = band_median(lab.b);
  constexpr float kDarkDrop = 6.0f, kDarkScale = 2.5f;  // darker than the reference by this much: terrain
  s.create(w, h, CV_32F);
  std::vector<float> scratch(6 * static_cast<size_t>(h));
  float* not_warm = scratch.data();
  float* deep_blue = not_warm + h;
  float* exp_light = deep_blue + h;
  float* exp_ref = exp_light + h;
  float* ref_at = exp_ref + h;
  float* ref_b_at = ref_at + h;
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    float* out = s.ptr<float>(c);
    // Sky: not darker than the sky above it, blue or neutral in hue (clouds,
    // haze); terrain is darker or green, yellow, brown or red. Saturated
    // blue is sky however dark (deep sky, sky below distant terrain); haze on
    // far ridges is paler than that.
    for (int r = 0; r < h; ++r) {
      const float warm = Logistic((b[r] - 6.0f) / 2.0f) + Logistic((std::abs(a[r]) - 10.0f) / 2.0f);
      not_warm[r] = warm < 1.0f ? 1.0f - warm : 0.0f;
      deep_blue[r] = DeepBlue(b[r], deep_blue_b);
    }
    auto exp_of_ref = [](float ref) { return ExpApprox((ref - kDarkDrop) * (1.0f / kDarkScale)); };
    for (int r = 0; r < h; ++r) {  // a loop apart: GCC vectorises at most 10 alias tests
      exp_light[r] = ExpApprox(l[r] * (-1.0f / kDarkScale));
      exp_ref[r] = exp_of_ref(l[r]);
    }
    // Reference lightness: the lightest blue sky seen so far down this
    // column (skies lighten towards the horizon; white clouds are left out).
    // The only sequential part, so it decides "sky score > 0.5" without the
    // logistic: (1 - dark) * not_warm > 0.5, with dark = logistic(x) and
    // x = (ref - drop - l) / scale, holds when e^x < 2 not_warm - 1.
    float ref = lm, ref_b = bm, exp_ref_now = exp_of_ref(lm);
    for (int r = 0; r < h; ++r) {
      ref_at[r] = ref;
      ref_b_at[r] = ref_b;
      if (b[r] < -8.0f && l[r] > ref &&
          (deep_blue[r] * not_warm[r] > 0.5f || exp_ref_now * exp_light[r] < 2.0f * not_warm[r] - 1.0f))
        ref = l[r], ref_b = b[r], exp_ref_now = exp_ref[r];
    }
    for (int r = 0; r < h; ++r) {
      const float dark = Logistic(((ref_at[r] - kDarkDrop) - l[r]) * (1.0f / kDarkScale));
      out[r] = std::max(1.0f - dark, deep_blue[r] * NotTooDark(l[r], ref_at[r], ref_b_at[r])) * not_warm[r];
    }
  }
  return lm;
}

// Clouds floating in the sky (FindFloatingClouds), per work column: the
// cloud's top row, the last row of the sky run under it, and the lowest
// first boundary within kFloatReach of the width (h, -1, 0 where none).
struct FloatingClouds {
  std::vector<int> top, sky_bottom, lowest;
  bool any = false;
};

// A cloud floating in the sky is white, so where the first boundary ran
// over its top the histograms learnt it (and the sky under it) as ground,
// and the DP kept the boundary on its top. Terrain does not float. Read
// down each column: the sky model's sky, then a blob lighter than the model
// by at least kFloatPeakSigmas at its peak (a cloud; a dark or shaded ridge
// or rock in snow is not one) down to where its departure falls below a
// quarter of that peak (at most kFloatRunSigmas), then kFloatSkyRows of the
// height that close to the model and not darker than it (the sky under the
// cloud), all above the lowest first boundary within kFloatReach of the
// width on either side (a lake or blue ice lower down is not sky).
FloatingClouds FindFloatingClouds(const LabPlanes& lab, const SkyModel& model, const std::vector<int>& boundary) {
  const int w = lab.Rows(), h = lab.Cols();
  FloatingClouds out;
  out.top.assign(w, h), out.sky_bottom.assign(w, -1), out.lowest.assign(w, 0);
  if (!model.fitted()) return out;
  const int reach = std::max(1, static_cast<int>(std::lround(kFloatReach * w)));
  const int need = std::max(3, static_cast<int>(std::lround(kFloatSkyRows * h)));
  const float inv = 1.0f / model.scale();
  std::vector<float> dev(h), lighter(h);
  std::deque<int> window;  // indices of the window's boundaries, decreasing rows (a sliding maximum)
  int next = 0;
  for (int c = 0; c < w; ++c) {
    for (; next < w && next <= c + reach; ++next) {
      while (!window.empty() && boundary[window.back()] <= boundary[next]) window.pop_back();
      window.push_back(next);
    }
    while (window.front() < c - reach) window.pop_front();
    const int lowest = std::min(h, boundary[window.front()]);
    out.lowest[c] = lowest;
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    // The departures, row by row as the reading needs them (most columns
    // are ruled out within their terrain's first dark rows).
    int known = 0;
    auto at = [&](int r) {
      for (float pred[3]; known <= r; ++known) {
        model.Predict(c, known, pred);
        const float dl = l[known] - pred[0], da = a[known] - pred[1], db = b[known] - pred[2];
        dev[known] = std::sqrt(dl * dl + da * da + db * db) * inv, lighter[known] = dl * inv;
      }
      return dev[r];
    };
    int r = 0;
    while (r < lowest && at(r) < kSkyModelClean) ++r;
    if (r < 2) continue;  // no sky above: a blob at the top edge may be terrain
    const int blob_top = r;
    int dark_rows = 0;
    float peak = 0.0f;
    for (; r < lowest; ++r) {
      peak = std::max(peak, at(r));
      if (peak >= kFloatPeakSigmas && dev[r] < std::min(kFloatRunSigmas, 0.25f * peak)) break;
      dark_rows += lighter[r] < -kSkyModelClean;
      if (dark_rows > (lowest - blob_top) / 10) break;  // too dark for a cloud however far it went
    }
    const int blob = r - blob_top;
    if (blob < 2 || peak < kFloatPeakSigmas || dark_rows > blob / 10) continue;
    const float limit = std::min(kFloatRunSigmas, 0.25f * peak);
    int run = 0;
    for (; r < lowest && run < need && at(r) < limit && lighter[r] > -kSkyModelVeto; ++r) ++run;
    if (run < need) continue;
    out.top[c] = blob_top, out.sky_bottom[c] = r - 1;
  }
  // A cloud spans kFloatMinColumns of the width at least, and the sky under
  // it continues beside it: the first boundary just outside the run (on at
  // least one side, kFloatMinColumns away) lies below the run's sky. A snowy
  // crest over a band of blue haze on the slope below it reads like a cloud
  // in its own column, but beside it the boundary is the crest's own line.
  const int min_run = std::max(4, static_cast<int>(std::lround(kFloatMinColumns * w)));
  for (int c0 = 0; c0 < w;) {
    if (out.sky_bottom[c0] < 0) {
      ++c0;
      continue;
    }
    int c1 = c0, sky_row = h;
    for (; c1 < w && out.sky_bottom[c1] >= 0; ++c1) sky_row = std::min(sky_row, out.sky_bottom[c1]);
    const int left = c0 - min_run, right = c1 - 1 + min_run;
    const bool beside = (left >= 0 && boundary[left] > sky_row) || (right < w && boundary[right] > sky_row);
    if (c1 - c0 >= min_run && beside)
      out.any = true;
    else
      for (int c = c0; c < c1; ++c) out.top[c] = h, out.sky_bottom[c] = -1;
    c0 = c1;
  }
  return out;
}

// Pass 2: sky probability from colour histograms of the pixels above
// sky_end[c] and below ground_start[c] in each column c (class-balanced
// likelihood ratio); of the rows between, only those marked in clean_sky
// (one row per column, CV_8U) are learnt, as sky.
HR_VECTOR_CLONES void SkyScoreFromHistograms(const LabPlanes& lab, const std::vector<int>& sky_end,
                                             const std::vector<int>& ground_start, const cv::Mat& clean_sky,
                                             cv::Mat& bins, cv::Mat& s) {
  const int w = lab.Rows(), h = lab.Cols();
  constexpr int kCells = kHistBins * kHistBins * kHistBins;
  std::vector<int> sky(kCells, 1), ground(kCells, 1);  // counts, from 1 each
  int ns = kCells, ng = kCells;
  bins.create(w, h, CV_32S);
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    int* bin = bins.ptr<int>(c);
    for (int r = 0; r < h; ++r) bin[r] = HistIndex(l[r], a[r], b[r]);
    const int se = std::clamp(sky_end[c], 0, h), gs = std::clamp(ground_start[c], 0, h);
    const uint8_t* clean = clean_sky.ptr<uint8_t>(c);
    for (int r = 0; r < se; ++r) ++sky[bin[r]];
    for (int r = se; r < gs; ++r)  // the band between: its clean sky (blue between clouds), not its snow
      if (clean[r]) ++sky[bin[r]], ++ns;
    for (int r = gs; r < h; ++r) ++ground[bin[r]];
    ns += se, ng += h - gs;
  }
  std::vector<float> p(kCells);
  for (int i = 0; i < kCells; ++i) {
    const double ps = static_cast<double>(sky[i]) / ns, pg = static_cast<double>(ground[i]) / ng;
    p[i] = static_cast<float>(std::clamp(ps / (ps + pg), 0.02, 0.98));
  }
  s.create(w, h, CV_32F);
  for (int c = 0; c < w; ++c) {
    const int* bin = bins.ptr<int>(c);
    float* out = s.ptr<float>(c);
    for (int r = 0; r < h; ++r) out[r] = p[bin[r]];
  }
}

// Colour step between rows y-1 and y from the mean colours of rows i0, i1
// above and i2, i3 below (see BoundarySteps).
inline float StepAt(const float* l, const float* a, const float* b, int i0, int i1, int i2, int i3, float deep_blue_b) {
  const float dl = 0.5f * (l[i2] + l[i3] - l[i0] - l[i1]), da = 0.5f * (a[i2] + a[i3] - a[i0] - a[i1]);
  const float below_b = 0.5f * (b[i2] + b[i3]), db = below_b - 0.5f * (b[i0] + b[i1]);
  // Any clear edge may be the skyline, not only the strongest: the reward
  // saturates (a faint far ridge above a contrasty near one).
  const float mag = std::min(std::sqrt(dl * dl + da * da + db * db), kEdgeCap);
  // A step down into saturated blue is within the sky (a cloud's base, the
  // renderer's or a real sky's deep blue near the horizon): terrain below
  // the skyline is never that blue, even far and hazy.
  // Unless the blue below is much darker than what is above (NotTooDark).
  const float into_deep_blue = DeepBlue(below_b, deep_blue_b) *
                               NotTooDark(0.5f * (l[i2] + l[i3]), 0.5f * (l[i0] + l[i1]), 0.5f * (b[i0] + b[i1]));
  return (dl > 2.0f ? 0.5f * mag : mag) * (1.0f - into_deep_blue);
}

// Colour step between rows y-1 and y: delta E between the means of rows
// (y, y+1) and (y-2, y-1), for y in [0, h]. Steps where the upper side is
// darker count half (sky is usually the brighter side). One row per image
// column.
HR_VECTOR_CLONES void BoundarySteps(const LabPlanes& lab, float deep_blue_b, cv::Mat& e) {
  const int w = lab.Rows(), h = lab.Cols();
  e.create(w, h + 1, CV_32F);
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    float* out = e.ptr<float>(c);
    out[0] = out[h] = 0.0f;
    auto clamped = [&](int y) {
      out[y] = StepAt(l, a, b, std::max(y - 2, 0), y - 1, y, std::min(y + 1, h - 1), deep_blue_b);
    };
    if (h > 1) clamped(1);
    for (int y = 2; y < h - 1; ++y) out[y] = StepAt(l, a, b, y - 2, y - 1, y, y + 1, deep_blue_b);
    if (h > 2) clamped(h - 1);
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

HR_VECTOR_CLONES void EdgeAbovePenalty(const cv::Mat& steps_t, const cv::Mat& sky_t, const LabPlanes& lab,
                                       EdgePenalty& pen) {
  const int w = sky_t.rows, h = sky_t.cols;
  pen.base.create(w, h, CV_32F);
  pen.extra.create(w, h, CV_32F);
  pen.blue.create(w, h, CV_8U);
  std::vector<float> blue(h);  // blue-sky likeness
  for (int c = 0; c < w; ++c) {
    const float* e = steps_t.ptr<float>(c);
    const float* s = sky_t.ptr<float>(c);
    const float* l = lab.l.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    float* base = pen.base.ptr<float>(c);
    float* extra = pen.extra.ptr<float>(c);
    uint8_t* is_blue = pen.blue.ptr<uint8_t>(c);
    float* bl = blue.data();
    for (int k = 0; k < h; ++k) {
      const float likeness = s[k] * Logistic((-b[k] - 8.0f) / 2.0f);
      bl[k] = s[k] > 0.05f && b[k] < 0.0f ? likeness : 0.0f;
    }
    for (int k = 0; k < h; ++k) is_blue[k] = bl[k] > 0.5f ? 1 : 0;
    // Row y, with y1, y2 the next two rows (clamped); the snow boost from
    // the colour at y2.
    auto at = [&](int y, int y1, int y2) {
      const float blue_sky = std::max(bl[y], std::max(bl[y1], bl[y2]));
      const float white = Logistic((l[y2] - 80.0f) * (1.0f / 3)) * Logistic((6.0f - std::abs(b[y2])) / 2.0f);
      base[y] = e[y] <= kEdgeNoise ? 0.0f : (e[y] - kEdgeNoise) * (1.0f - blue_sky);
      extra[y] = base[y] * kSnowEdgeBoost * white;
    };
    for (int y = 0; y < h - 2; ++y) at(y, y + 1, y + 2);
    for (int y = std::max(0, h - 2); y < h; ++y) at(y, std::min(y + 1, h - 1), h - 1);
  }
}

// Rows the expected slope moves the boundary from column c - 1 to c (0 for
// the first column), for w columns.
std::vector<int> SlopeShifts(int w, double slope_px_per_col) {
  std::vector<int> shift(w, 0);
  for (int c = 1; c < w; ++c)
    shift[c] = static_cast<int>(std::lround(c * slope_px_per_col) - std::lround((c - 1) * slope_px_per_col));
  return shift;
}

// The back-trace of a column DP over `acc` (n = h + 1 accumulated costs per
// column, column_min their minima): the best last row, then per column the
// previous column's row that reached it most cheaply (the first of equals),
// searched outwards until the jump alone (beta per row) costs more than the
// best found.
std::vector<int> TraceBack(const std::vector<float>& acc, const std::vector<float>& column_min,
                           const std::vector<int>& shift, int n, float beta) {
  const int w = static_cast<int>(shift.size()), h = n - 1;
  std::vector<int> out(w);
  const float* last = acc.data() + static_cast<size_t>(w - 1) * n;
  out[w - 1] = static_cast<int>(std::min_element(last, last + n) - last);
  for (int c = w - 1; c > 0; --c) {
    const float* a = acc.data() + static_cast<size_t>(c - 1) * n;
    const int o = out[c];
    float best = INFINITY;
    int best_y = n;
    auto consider = [&](int y) {
      const float v = a[std::clamp(y - shift[c], 0, h)] + beta * static_cast<float>(std::abs(o - y));
      if (v < best || (v == best && y < best_y)) best = v, best_y = y;
    };
    consider(o);
    for (int d = 1; (o - d >= 0 || o + d < n) && column_min[c - 1] + beta * static_cast<float>(d) <= best; ++d) {
      if (o - d >= 0) consider(o - d);
      if (o + d < n) consider(o + d);
    }
    out[c - 1] = std::clamp(best_y - shift[c], 0, h);
  }
  return out;
}

// The frame's top edge as a boundary: where a column's top rows are
// terrain (a slope or a ridge that leaves the frame upwards, as a camera
// held askew or pitched down frames it), the sky lies above the frame and
// the top edge is the step from it. Without a reward there, the slope's
// foot on brighter snow or ice earned the step's and was taken for the
// skyline, and the slope was learnt as sky (a copy of AK10_20090803 turned
// by 6 deg: 224 columns read 10-40 px under a slope that fills the frame's
// top left corner). The reward is the top rows' drop in lightness below
// the sky's (`sky_l`, the top band's median), capped as a step is, times
// how little they look like sky (`sky_t`'s first two rows), times how much
// rougher they are than the tops of the columns that look like sky (the
// median of those, each column's roughness its mean absolute Laplacian
// over its top rows, 5 columns averaged): rock and forest are textured, a
// sky darkened towards a corner (a lens's vignetting, the deep blue of a
// polarised zenith) is as smooth as the rest of the sky (measured on the
// turned copies: the slope 1.5-7 times the sky's roughness, CG05_20050827's
// dark blue corner 0.6-1.6).
void TopEdgeReward(const LabPlanes& lab, const cv::Mat& sky_t, float sky_l, std::vector<float>& out) {
  const int w = lab.Rows(), h = lab.Cols();
  out.assign(w, 0.0f);
  if (h < 4 || w < 3) return;
  const int rows = std::min(h - 1, std::max(3, h / 40));
  std::vector<float> top_sky(w), tex(w, 0.0f), sky_tex;  // the top rows' sky likeness and roughness
  for (int c = 0; c < w; ++c) top_sky[c] = 0.5f * (sky_t.ptr<float>(c)[0] + sky_t.ptr<float>(c)[1]);
  for (int c = 1; c + 1 < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* lp = lab.l.ptr<float>(c - 1);
    const float* ln = lab.l.ptr<float>(c + 1);
    float sum = 0;
    for (int r = 1; r < rows; ++r) sum += std::abs(l[r] - 0.25f * (l[r - 1] + l[r + 1] + lp[r] + ln[r]));
    tex[c] = sum / (rows - 1);
    if (top_sky[c] > 0.5f) sky_tex.push_back(tex[c]);
  }
  tex[0] = tex[1], tex[w - 1] = tex[w - 2];
  std::vector<float> smooth(w);
  for (int c = 0; c < w; ++c) {
    const int a = std::max(0, c - 2), b = std::min(w - 1, c + 2);
    float sum = 0;
    for (int k = a; k <= b; ++k) sum += tex[k];
    smooth[c] = sum / (b - a + 1);
  }
  if (sky_tex.size() < 3) return;
  std::nth_element(sky_tex.begin(), sky_tex.begin() + sky_tex.size() / 2, sky_tex.end());
  const float ref = std::max(sky_tex[sky_tex.size() / 2], 0.05f);
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float drop = sky_l - 0.5f * (l[0] + l[1]);
    const float textured = Logistic((smooth[c] / ref - 2.0f) * 3.0f);
    out[c] = std::clamp(drop, 0.0f, kEdgeCap) * (1.0f - top_sky[c]) * textured;
  }
}

// Globally best boundary (one y in [0, h] per column): misclassified pixels
// (sky below or non-sky above) minus the colour step at the boundary, plus
// `smoothness` per pixel of jump, around the slope expected from the roll.
std::vector<int> SolveBoundary(const cv::Mat& sky_t, const cv::Mat& steps_t, const EdgePenalty& penalty,
                               double smoothness, double edge_weight, double slope_px_per_col,
                               std::vector<float>& acc, const std::vector<float>* top_reward = nullptr) {
  const int w = sky_t.rows, h = sky_t.cols, n = h + 1;
  std::vector<float> data(n), forward(n), ramp(n), pen(n + 1), pen_extra(n + 1), zeros(n, 0.0f), column_min(w);
  const float beta = static_cast<float>(smoothness), lambda = static_cast<float>(edge_weight);
  for (int y = 0; y < n; ++y) ramp[y] = beta * static_cast<float>(y);
  const std::vector<int> shift = SlopeShifts(w, slope_px_per_col);
  acc.resize(static_cast<size_t>(w) * n);
  for (int c = 0; c < w; ++c) {
    // The previous column's costs (none before the first), shifted by the
    // slope and spread by an L1 distance transform, min over k of
    // prev[k] + beta |y - k|: running minima of prev[k] - beta k downwards
    // and of prev[k] + beta k upwards (the argmins are recovered when tracing
    // back). Plus the column's own cost: misclassified pixels (non-sky above
    // the boundary, sky below it; the column's sky total, the same for every
    // y, is left out), minus the colour step at the boundary, plus the sharp
    // steps left above it (the paper scans from the top for the first edge):
    // each costs its excess over the noise level unless it leads into sky
    // (EdgeAbovePenalty); steps within 2 rows above the boundary are its own
    // (the 4-tap step spreads an edge over 3 rows).
    const float* prev = c > 0 ? acc.data() + static_cast<size_t>(c - 1) * n : zeros.data();
    auto prev_at = [&, sh = shift[c]](int y) { return prev[std::clamp(y - sh, 0, h)]; };
    const float* s = sky_t.ptr<float>(c);
    const float* e = steps_t.ptr<float>(c);
    const float* p = penalty.base.ptr<float>(c);
    const float* px = penalty.extra.ptr<float>(c);
    const uint8_t* blue = penalty.blue.ptr<uint8_t>(c);
    // Running sums in registers (through the arrays, each step would wait
    // for the store of the one before).
    float sky_above = 0, pen_sum = 0, extra_sum = 0, run = INFINITY;
    pen[0] = pen_extra[0] = 0;
    int after_blue = 0;  // first row below the last blue-sky row above the boundary's margin
    for (int y = 0; y <= h; ++y) {
      const int top = std::max(0, y - 2);  // rows [0, top) lie above the boundary's own step
      if (top > 0 && blue[top - 1]) after_blue = top;
      const float snow = pen_extra[top] - pen_extra[after_blue];
      const float misclassified = static_cast<float>(y) - 2.0f * sky_above;
      data[y] = kColourWeight * misclassified + kEdgeAboveWeight * (pen[top] + snow) - lambda * e[y];
      if (y == 0 && top_reward) data[0] -= lambda * (*top_reward)[c];
      run = std::min(run, prev_at(y) - ramp[y]);
      forward[y] = run + ramp[y];
      if (y == h) break;
      sky_above += s[y], pen_sum += p[y], extra_sum += px[y];
      pen[y + 1] = pen_sum, pen_extra[y + 1] = extra_sum;
    }
    float* cur = acc.data() + static_cast<size_t>(c) * n;
    float lowest = INFINITY;
    run = INFINITY;
    for (int y = h; y >= 0; --y) {
      run = std::min(run, prev_at(y) + ramp[y]);
      cur[y] = std::min(forward[y], run - ramp[y]) + data[y];
      lowest = std::min(lowest, cur[y]);
    }
    column_min[c] = lowest;
  }
  return TraceBack(acc, column_min, shift, n, beta);
}

// Globally best boundary for a given unary cost (one row of `unary` per
// column, n = h + 1 entries: the boundary between rows y - 1 and y), with
// `smoothness` per pixel of jump around the slope the roll predicts: the
// L1 distance transform as running minima, then the back-trace.
std::vector<int> SolveUnary(const cv::Mat& unary, double smoothness, double slope_px_per_col, std::vector<float>& acc) {
  const int w = unary.rows, n = unary.cols, h = n - 1;
  const float beta = static_cast<float>(smoothness);
  std::vector<float> forward(n), ramp(n), column_min(w);
  for (int y = 0; y < n; ++y) ramp[y] = beta * static_cast<float>(y);
  const std::vector<int> shift = SlopeShifts(w, slope_px_per_col);
  acc.resize(static_cast<size_t>(w) * n);
  for (int c = 0; c < w; ++c) {
    const float* u = unary.ptr<float>(c);
    float* cur = acc.data() + static_cast<size_t>(c) * n;
    if (c == 0) {
      std::copy(u, u + n, cur);
      column_min[0] = *std::min_element(cur, cur + n);
      continue;
    }
    const float* prev = acc.data() + static_cast<size_t>(c - 1) * n;
    auto prev_at = [&, sh = shift[c]](int y) { return prev[std::clamp(y - sh, 0, h)]; };
    float run = INFINITY;
    for (int y = 0; y < n; ++y) {
      run = std::min(run, prev_at(y) - ramp[y]);
      forward[y] = run + ramp[y];
    }
    run = INFINITY;
    float lowest = INFINITY;
    for (int y = h; y >= 0; --y) {
      run = std::min(run, prev_at(y) + ramp[y]);
      cur[y] = std::min(forward[y], run - ramp[y]) + u[y];
      lowest = std::min(lowest, cur[y]);
    }
    column_min[c] = lowest;
  }
  return TraceBack(acc, column_min, shift, n, beta);
}

// Persistent colour steps: per column and boundary y, the change between the
// mean colours of the k rows below and of the k rows above, measured both
// plainly and against the linear trend of the 2k rows above (a sky's smooth
// gradient is no step), the smaller of the two (next to another edge the
// trend is meaningless). A step down into saturated blue is within the sky
// (a deep sky below a pale one, a cloud's base), so it counts nothing.
HR_VECTOR_CLONES void PersistentSteps(const LabPlanes& lab, int k, float deep_blue_b, cv::Mat& out) {
  const int w = lab.Rows(), h = lab.Cols();
  out.create(w, h + 1, CV_32F);
  out.setTo(0.0f);
  if (h < 2 * k + 2) return;
  std::vector<float> cl(h + 1), ca(h + 1), cb(h + 1), plain(h + 1), trend(h + 1);
  const float inv_k = 1.0f / static_cast<float>(k);
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    cl[0] = ca[0] = cb[0] = 0.0f;
    for (int r = 0; r < h; ++r) cl[r + 1] = cl[r] + l[r], ca[r + 1] = ca[r] + a[r], cb[r + 1] = cb[r] + b[r];
    // Means of the k rows above (u), below (d) and the k before those (v):
    // the plain step |d - u| and the step against the trend |d - (2u - v)|.
    const int end = h - k;  // y + k <= h
    for (int y = k; y <= end; ++y) {
      const float ul = cl[y] - cl[y - k], ua = ca[y] - ca[y - k], ub = cb[y] - cb[y - k];
      const float dl = cl[y + k] - cl[y], da = ca[y + k] - ca[y], db = cb[y + k] - cb[y];
      plain[y] = inv_k * std::sqrt((dl - ul) * (dl - ul) + (da - ua) * (da - ua) + (db - ub) * (db - ub));
    }
    for (int y = 2 * k; y <= end; ++y) {
      const float ul = cl[y] - cl[y - k], ua = ca[y] - ca[y - k], ub = cb[y] - cb[y - k];
      const float vl = cl[y - k] - cl[y - 2 * k], va = ca[y - k] - ca[y - 2 * k], vb = cb[y - k] - cb[y - 2 * k];
      const float el = cl[y + k] - cl[y] - 2 * ul + vl, ea = ca[y + k] - ca[y] - 2 * ua + va,
                  eb = cb[y + k] - cb[y] - 2 * ub + vb;
      trend[y] = inv_k * std::sqrt(el * el + ea * ea + eb * eb);
    }
    for (int y = k; y < 2 * k && y <= end; ++y) trend[y] = plain[y];
    float* o = out.ptr<float>(c);
    // The k rows past the transition (from 2 rows below y, clamped at the
    // bottom): saturated blue, unless much darker than the k rows above.
    for (int y = k; y <= end; ++y) {
      const int lo = std::min(y + 2, end);
      const float into =
          DeepBlue((cb[lo + k] - cb[lo]) * inv_k, deep_blue_b) *
          NotTooDark((cl[lo + k] - cl[lo]) * inv_k, (cl[y] - cl[y - k]) * inv_k, (cb[y] - cb[y - k]) * inv_k);
      o[y] = std::min(plain[y], trend[y]) * (1.0f - into);
    }
  }
}

// The noise of the top fifth of the image and of the sky in it: the median
// persistent step of all its rows, and of those whose steps lie above the
// first boundary `sky_below` (where the sky is a thin strip, the terrain's
// texture below it is no measure of the sky's), unless that leaves fewer
// than two rows (then the whole top fifth's). But the first pass takes
// white snow for sky, so over snow `sky_below` can lie deep in the terrain,
// and a thin strip of sky leaves the top fifth mostly terrain. So each
// reading is set against the rows above each column's first clear step
// (beyond kSkyNoiseClearStep delta E and kSkyNoiseClearFactor times the top
// fifth's noise; at least a quarter row of them per column sampled): from
// kSkyNoiseTextureRatio times theirs (what lay below them was textured
// terrain) it moves towards theirs, which it is from kSkyNoiseTextureFull
// times on (log-linear between: no photo flips at one ratio). Measured on
// the real photos cropped to 10 px of sky above their highest point:
// AKJNC_20120605 read 2.1 delta E for the sky (0.8 above the first clear
// steps, 0.6 uncropped), and its contrast floor of 10.3 delta E nulled 336
// of its 972 columns; with its foreground of rock cut as well (snow and ice
// to the bottom of the frame), the top fifth read 2.3 and the topmost edge
// (which needs a step of 5 times that) left a hazy saddle's 11 delta E for
// the glacier 130 rows below: 30% of its traced columns within 2 px, 82%
// with both readings mended. Over the photos so cropped (`eval_real.py
// --modes thin,thin-framed`): 77.0% -> 78.3% and 72.2% -> 78.9% of the
// traced columns within 2 px. No photo as taken changes (the highest ratio,
// AK01b_20100602's top fifth, is 1.97), and two rendered scenes under
// clouds by 12 and 18 columns (zion_02 97.6% -> 96.3%; all 97.5% -> 97.3%).
// Below that ratio (a haze band, a sky's gradient, clouds above the first
// clear step: fuji_02's cloud texture reads 1.6 times the sky above it,
// and its topmost edge from the sky's reading took cloud edges for
// terrain, 79% -> 32% within 2 px) the readings stand. Taking the lower
// reading of the sky whenever lower (AK01b_20100525 1.01 -> 0.68,
// AK01b_20100602 0.85 -> 0.61 as taken) gave the photos 81.1% of their
// traced columns within 2 px instead of 80.6%, but registered
// AK01b_20100602 from 2 km beside its station 2.6 deg off (a ring probe:
// the position check's best place at a cost ratio of 0.903, the limit
// 0.90). Two scans (the second needs the first's top noise).
struct TopNoise {
  float top = 0.1f, sky = 0.1f;  // delta E
};
constexpr float kSkyNoiseClearStep = 3.0f;
constexpr float kSkyNoiseClearFactor = 2.5f;
constexpr float kSkyNoiseTextureRatio = 2.0f;  // from this ratio on, the reading moves towards the smooth one ...
constexpr float kSkyNoiseTextureFull = 3.0f;   // ... which it is from this ratio on (log-linear between)
TopNoise MeasureTopNoise(const cv::Mat& steps, const std::vector<int>& sky_below) {
  const int w = steps.rows, h = steps.cols - 1;
  std::vector<float> sky, rest;
  const int top_rows = std::min(h, std::max(8, h / 5));
  for (int c = 0; c < w; c += 2) {
    const float* s = steps.ptr<float>(c);
    const int end = std::min(top_rows, sky_below[c] - kPersistentRows);
    for (int y = kPersistentRows; y < top_rows; ++y) (y < end ? sky : rest).push_back(s[y]);
  }
  auto median = [](std::vector<float> v) {
    if (v.empty()) return 0.1f;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return std::max(0.1f, v[v.size() / 2]);
  };
  TopNoise out;
  const bool enough_sky = sky.size() >= static_cast<size_t>(w);
  if (enough_sky) out.sky = median(sky);
  std::vector<float> all(sky);
  all.insert(all.end(), rest.begin(), rest.end());
  out.top = median(all);
  if (!enough_sky) out.sky = out.top;
  // The rows above each column's first clear step (the step's persistent
  // rows left out).
  const float clear = std::max(kSkyNoiseClearStep, kSkyNoiseClearFactor * out.top);
  std::vector<float> above_clear;
  for (int c = 0; c < w; c += 2) {
    const float* s = steps.ptr<float>(c);
    const int end = std::min(top_rows, sky_below[c] - kPersistentRows);
    int stop = end;
    for (int y = kPersistentRows; y < end; ++y)
      if (s[y] > clear) {
        stop = y - kPersistentRows;
        break;
      }
    for (int y = kPersistentRows; y < stop; ++y) above_clear.push_back(s[y]);
  }
  if (above_clear.size() >= static_cast<size_t>(w / 4)) {
    const float smooth = median(above_clear);
    auto towards_smooth = [&](float reading) {
      const float t = std::clamp(std::log(reading / (kSkyNoiseTextureRatio * smooth)) /
                                     std::log(kSkyNoiseTextureFull / kSkyNoiseTextureRatio),
                                 0.0f, 1.0f);
      return std::exp((1.0f - t) * std::log(reading) + t * std::log(smooth));
    };
    out.sky = towards_smooth(out.sky);
    out.top = towards_smooth(out.top);
  }
  return out;
}

// The paper's first sharp edge from the top, made global: the boundary with
// a clear persistent step, whose rows above hold no clear step. "Clear" is
// relative to the noise of the top of the image (`noise`, TopNoise::top), so a
// faint ridge in haze counts when the sky above it is smooth. Returns the
// boundary per column (work size).
std::vector<int> TopmostEdge(const cv::Mat& steps, float noise, double smoothness, double slope, cv::Mat& unary,
                             std::vector<float>& acc) {
  const int w = steps.rows, n = steps.cols;
  const float thr = std::max(kTopmostMinStep, kTopmostNoiseFactor * noise), cap = 3.0f * thr;
  unary.create(w, n, CV_32F);
  for (int c = 0; c < w; ++c) {
    const float* s = steps.ptr<float>(c);
    float* u = unary.ptr<float>(c);
    float above = 0.0f;  // clear steps more than 2 rows above y
    for (int y = 0; y < n; ++y) {
      if (y >= 3) above += std::max(0.0f, s[y - 3] - thr);
      u[y] = -std::min(s[y], cap) + kTopmostAboveWeight * above;
    }
  }
  return SolveUnary(unary, smoothness, slope, acc);
}

// Sky probability times (1 - veto): the veto is near 1 where a pixel departs
// from the sky model by more than kSkyModelVeto sigmas but less than
// kSubtleDeltaE, unless saturated blue.
HR_VECTOR_CLONES void VetoSubtleDepartures(const cv::Mat& deviation, const LabPlanes& lab, float sky_scale,
                                           float deep_blue_b, cv::Mat& sky) {
  const int w = sky.rows, h = sky.cols;
  for (int c = 0; c < w; ++c) {
    const float* dev = deviation.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    float* s = sky.ptr<float>(c);
    for (int r = 0; r < h; ++r) {
      const float off = Logistic((dev[r] - kSkyModelVeto) * 2.0f) *
                        Logistic((kSubtleDeltaE - dev[r] * sky_scale) * (1.0f / 1.5f)) *
                        (1.0f - DeepBlue(b[r], deep_blue_b));
      s[r] *= 1.0f - off;
    }
  }
}

// Thin lines across the sky (power lines, a cable): per work
// column, a run of 1-kLineMaxRows rows that departs by more than
// kLineDeltaE (and 2.5 times their own difference) from the two rows either
// side of it, those rows within kLineSameDeltaE of each other and each as
// light as its outer neighbour to within that (lightness only: JPEG bleeds
// a dark line's chroma into the rows beside it). Runs that continue one
// another over at least 1/kLineTrackShare of the width, and lie on a line
// over kLineStraightColumns columns each side, are replaced by the line
// between the rows either side. The sky/terrain boundary is no such run
// (the colours above and below it differ), texture's runs are short, and a
// thin crest between an overcast sky and snow of its colour bends. Wider,
// soft bands (a contrail, a strip of cloud: more than kLineMaxRows rows)
// must leave the colour of the row above within kBandOnsetRows, come back to
// it, be lighter than both rows either side all through (a far ridge in
// haze between a pale sky and snow of its colour is darker) and track over
// 1/kBandTrackShare of the width. Measured on the real photos with two
// cables, or two contrails, across their sky: docs/MEASUREMENTS.md, "Cables
// across the sky" and "Contrails across the sky".
constexpr float kLineSameDeltaE = 3.0f;
constexpr float kLineDeltaE = 4.0f;
constexpr int kLineMaxRows = 5;
constexpr int kLineStraightColumns = 16;  // columns each side over which a cable's runs lie on a line ...
constexpr double kLineStraightRows = 2.0;  // ... to within this many rows
constexpr int kLineTrackStep = 4;  // a track continues over up to 3 columns where no run was found
constexpr int kLineTrackShare = 12;  // a track spans at least 1/12 of the work width (and 8 columns)
constexpr int kBandRows = 24;       // a band's rows from the one above it to the one below (per 512 columns) ...
constexpr int kBandOnsetRows = 4;   // ... its colour leaving that of the row above within this many rows ...
constexpr int kBandTrackShare = 6;  // ... and its track spanning at least 1/6 of the work width
HR_VECTOR_CLONES void EraseThinLines(LabPlanes& lab, std::vector<uint8_t>& run_len, std::vector<uint16_t>& left,
                                     std::vector<uint16_t>& right) {
  const int w = lab.Rows(), h = lab.Cols();
  const int min_track = std::max(8, w / kLineTrackShare);
  const int band_rows = std::clamp(w * kBandRows / 512, kLineMaxRows + 2, 250);  // run lengths are 8-bit
  const int min_band_track = std::max(8, w / kBandTrackShare);
  const size_t n = static_cast<size_t>(w) * h;
  run_len.assign(n, 0);
  constexpr float same2 = kLineSameDeltaE * kLineSameDeltaE;
  bool any = false;
  for (int c = 0; c < w; ++c) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    auto de2 = [&](int i, int j) {
      const float dl = l[i] - l[j], da = a[i] - a[j], db = b[i] - b[j];
      return dl * dl + da * da + db * db;
    };
    // Rows r..dn-1 stand out from the rows either side, up and dn: some row
    // departs from both by kLineDeltaE and by 2.5 times their own difference.
    auto stands_out = [&](int r, int up, int dn) {
      float peak2 = 0.0f;
      for (int k = r; k < dn; ++k) peak2 = std::max(peak2, std::min(de2(k, up), de2(k, dn)));
      return peak2 >= std::max(kLineDeltaE * kLineDeltaE, 6.25f * de2(up, dn));
    };
    uint8_t* runs = run_len.data() + static_cast<size_t>(c) * h;
    for (int r = 2; r + 3 < h; ++r) {
      const int up = r - 1;
      if (std::abs(l[up - 1] - l[up]) > kLineSameDeltaE) continue;
      // No row within reach departs from the row above by kLineDeltaE: no
      // run starts here (most rows of a smooth sky or of terrain).
      float reach2 = 0.0f;
      for (int k = r; k < std::min(h, r + kLineMaxRows); ++k) reach2 = std::max(reach2, de2(k, up));
      if (reach2 < kLineDeltaE * kLineDeltaE) continue;
      for (int len = 1; len <= kLineMaxRows; ++len) {
        const int dn = r + len;  // the rows either side: up and dn
        if (dn + 1 >= h) break;
        if (std::abs(l[dn] - l[dn + 1]) > kLineSameDeltaE) continue;
        if (de2(up, dn) > same2 || !stands_out(r, up, dn)) continue;
        runs[r] = static_cast<uint8_t>(len);
        any = true;
        break;
      }
      if (!runs[r]) {
        // A wider, soft band (a contrail, a strip of cloud): the rows leave
        // the colour of the row above within kBandOnsetRows and come back to
        // it (to within kLineSameDeltaE) within band_rows of it.
        const int last = std::min(h - 2, up + band_rows);
        int k = r, left_at = -1;
        for (; k <= last; ++k) {
          const bool off = de2(k, up) > same2;
          if (left_at < 0) {
            if (off) left_at = k;
            else if (k - up >= kBandOnsetRows) break;
          } else if (!off) {
            break;
          }
        }
        const int dn = k;
        if (left_at >= 0 && dn <= last && dn - r > kLineMaxRows && std::abs(l[dn] - l[dn + 1]) <= kLineSameDeltaE) {
          // Lighter than the sky either side all through: a far ridge's
          // darker band between a pale sky and snow of its colour is terrain.
          const float floor_l = std::max(l[up], l[dn]);
          const bool lighter = std::all_of(l + left_at, l + dn, [&](float li) { return li > floor_l; });
          if (lighter && stands_out(r, up, dn)) {
            runs[r] = static_cast<uint8_t>(dn - r);
            any = true;
          }
        }
      }
      r += runs[r];
    }
  }
  if (!any) return;
  // The longest track through each run, from the left and from the right.
  left.assign(n, 0);
  right.assign(n, 0);
  // A track continues from a run k columns on (start row within k), over up
  // to kLineTrackStep - 1 columns where none was found.
  auto longest = [&](const std::vector<uint16_t>& v, int c, int r, int step) {
    uint16_t best = 0;
    for (int k = 1; k <= kLineTrackStep; ++k) {
      const int cc = c + k * step;
      if (cc < 0 || cc >= w) break;
      for (int d = std::max(0, r - k); d <= std::min(h - 1, r + k); ++d)
        best = std::max(best, v[static_cast<size_t>(cc) * h + d]);
    }
    return best;
  };
  for (int c = 0; c < w; ++c)
    for (int r = 0; r < h; ++r)
      if (run_len[static_cast<size_t>(c) * h + r])
        left[static_cast<size_t>(c) * h + r] = static_cast<uint16_t>(longest(left, c, r, -1) + 1);
  for (int c = w - 1; c >= 0; --c)
    for (int r = 0; r < h; ++r)
      if (run_len[static_cast<size_t>(c) * h + r])
        right[static_cast<size_t>(c) * h + r] = static_cast<uint16_t>(longest(right, c, r, 1) + 1);
  // A cable is straight over a few dozen columns (a catenary's sag bends it
  // by a tenth of a row there); a crest that thin between two equal colours
  // (dark rock between an overcast sky and snow) bends or is jagged.
  auto straight = [&](int c, int r) {
    double m = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    std::array<std::pair<int, int>, 2 * kLineStraightColumns + 1> pts;
    int count = 0;
    pts[count++] = {c, r};
    for (const int step : {-1, 1}) {
      int cr = r, gap = 0;
      for (int k = 1; k <= kLineStraightColumns; ++k) {
        const int cc = c + k * step;
        if (cc < 0 || cc >= w) break;
        int found = -1;
        for (int d = 0; d <= 1 + gap && found < 0; ++d)
          for (const int rr : {cr - d, cr + d})
            if (rr >= 0 && rr < h && run_len[static_cast<size_t>(cc) * h + rr]) {
              found = rr;
              break;
            }
        if (found < 0) {
          if (++gap >= kLineTrackStep) break;
          continue;
        }
        gap = 0;
        cr = found;
        pts[count++] = {cc, cr};
      }
    }
    if (count < kLineStraightColumns) return false;
    for (int k = 0; k < count; ++k) {
      const double x = pts[k].first - c, y = pts[k].second;
      m += 1, sx += x, sy += y, sxx += x * x, sxy += x * y;
    }
    const double den = m * sxx - sx * sx;
    if (!(den > 0)) return false;
    const double slope = (m * sxy - sx * sy) / den, icpt = (sy - slope * sx) / m;
    for (int k = 0; k < count; ++k)
      if (std::abs(pts[k].second - (icpt + slope * (pts[k].first - c))) > kLineStraightRows) return false;
    return true;
  };
  for (int c = 0; c < w; ++c) {
    float* l = lab.l.ptr<float>(c);
    float* a = lab.a.ptr<float>(c);
    float* b = lab.b.ptr<float>(c);
    for (int r = 0; r < h; ++r) {
      const size_t i = static_cast<size_t>(c) * h + r;
      const int len = run_len[i];
      if (!len || left[i] + right[i] - 1 < (len > kLineMaxRows ? min_band_track : min_track) || !straight(c, r))
        continue;
      const int up = r - 1, dn = r + len;
      for (int k = r; k < dn; ++k) {
        const float t = static_cast<float>(k - up) / static_cast<float>(dn - up);
        l[k] = l[up] + t * (l[dn] - l[up]), a[k] = a[up] + t * (a[dn] - a[up]), b[k] = b[up] + t * (b[dn] - b[up]);
      }
    }
  }
}

constexpr int kMaxBoxFactor = 257;  // BoxReduce's column sums of k bytes fit 16 bits

// The mean of each k x k block of an 8-bit BGR image, rounded (the last
// < k rows and columns are dropped). cv::resize's INTER_AREA does this
// pixel by pixel for k > 2 (13 ms for 4000 x 3000 at k = 7); here whole
// rows are summed first, which vectorises. k in [2, kMaxBoxFactor].
HR_VECTOR_CLONES void BoxReduce(const cv::Mat& bgr, int k, std::vector<uint16_t>& row_sums, cv::Mat& out) {
  const int rows = bgr.rows / k, cols = bgr.cols / k, width = 3 * cols * k;
  out.create(rows, cols, CV_8UC3);
  row_sums.resize(width);
  uint16_t* sum = row_sums.data();
  const float inv_area = 1.0f / static_cast<float>(k * k);
  for (int r = 0; r < rows; ++r) {
    std::fill(row_sums.begin(), row_sums.end(), uint16_t{0});
    for (int i = 0; i < k; ++i) {
      const uint8_t* in = bgr.ptr<uint8_t>(r * k + i);
      for (int j = 0; j < width; ++j) sum[j] = static_cast<uint16_t>(sum[j] + in[j]);
    }
    uint8_t* o = out.ptr<uint8_t>(r);
    for (int c = 0; c < cols; ++c)
      for (int ch = 0; ch < 3; ++ch) {
        int block = 0;
        for (int m = 0; m < k; ++m) block += sum[3 * (c * k + m) + ch];
        o[3 * c + ch] = static_cast<uint8_t>(static_cast<float>(block) * inv_area + 0.5f);
      }
  }
}

// Images are extracted at about this width: the refinement's rows and
// thresholds (steps between neighbouring rows, colours 2-4 rows from the
// edge, the raises' rows per 1024 columns) are tuned at it. A wider image's
// edges spread over more rows (the lens, the demosaicing, the haze), and
// read at full size they turned faint: the real photos upscaled 4x lost
// half the columns of the hazy CG05 ones to the contrast test.
constexpr int kExtractWidth = 1024;

// A skyline extracted from an image reduced k times (BoxReduce: reduced
// pixel i covers full-size pixels k i .. k i + k - 1, so boundaries scale
// by k exactly) mapped to the full size: each column interpolated between
// the two reduced columns around its centre, or the nearer one's where the
// other has none (none where the nearer has none).
Skyline MappedUp(const Skyline& s, int k, int width, int height) {
  Skyline out;
  out.width = width;
  out.height = height;
  out.y.assign(width, NAN);
  out.confidence.assign(width, 0.0);
  if (!s.y_alt.empty()) out.y_alt.assign(width, NAN);
  const int n = s.width;
  if (n < 1) return out;
  auto at = [&](const std::vector<double>& v, double u) {
    const int i0 = std::clamp(static_cast<int>(std::floor(u)), 0, n - 1), i1 = std::min(i0 + 1, n - 1);
    const double f = std::clamp(u - i0, 0.0, 1.0);
    if (std::isfinite(v[i0]) && std::isfinite(v[i1])) return (1.0 - f) * v[i0] + f * v[i1];
    return f < 0.5 ? v[i0] : v[i1];
  };
  for (int x = 0; x < width; ++x) {
    const double u = (x + 0.5) / k - 0.5;
    if (const double y = at(s.y, u); std::isfinite(y)) {
      out.y[x] = std::clamp(k * y, 0.0, static_cast<double>(height));
      out.confidence[x] = s.confidence[std::clamp(static_cast<int>(std::lround(u)), 0, n - 1)];
    }
    if (!s.y_alt.empty())
      if (const double a = at(s.y_alt, u); std::isfinite(a) && std::isfinite(out.y[x]))
        out.y_alt[x] = std::clamp(k * a, 0.0, static_cast<double>(height));
  }
  return out;
}

// The full-size row of a boundary mapped up from an image reduced k times
// (MappedUp), which placed it to within about half a reduced row: the
// half-way crossing of the column's colours (averaged over the k columns
// around it) from the sky's, 2k to 3k rows above, to the ground's, 2k to 3k
// rows below, nearest the mapped boundary and within k rows of it. Kept
// where the two differ by less than kPolishMinContrast or no crossing lies
// that near. NaN stays NaN.
constexpr double kPolishMinContrast = 12.0;  // BGR distance (about 4 delta E)

double PolishedRow(const cv::Mat& bgr, int k, int x, double y) {
  if (!std::isfinite(y)) return y;
  const int h = bgr.rows, w = bgr.cols, yi = static_cast<int>(std::floor(y));
  if (yi - 3 * k < 0 || yi + 3 * k > h) return y;
  const int c0 = std::max(0, x - k / 2), c1 = std::min(w - 1, x - k / 2 + k - 1);
  auto colour = [&](int r) {
    cv::Vec3d m(0, 0, 0);
    const cv::Vec3b* row = bgr.ptr<cv::Vec3b>(r);
    for (int c = c0; c <= c1; ++c) m += cv::Vec3d(row[c]);
    return m / static_cast<double>(c1 - c0 + 1);
  };
  cv::Vec3d sky(0, 0, 0), ground(0, 0, 0);
  for (int i = 0; i < k; ++i) sky += colour(yi - 3 * k + i), ground += colour(yi + 2 * k + i);
  sky /= k, ground /= k;
  const cv::Vec3d d = ground - sky;
  const double dd = d.dot(d);
  if (dd < kPolishMinContrast * kPolishMinContrast) return y;
  auto share = [&](int r) { return (colour(r) - sky).dot(d) / dd; };  // 0 at the sky's colour, 1 at the ground's
  double best = y, best_gap = k + 1e-9;
  double before = share(yi - k - 1);
  for (int r = yi - k; r <= yi + k; ++r) {
    const double t = share(r);
    if (before < 0.5 && t >= 0.5) {
      // Row r - 1's centre at r - 0.5, row r's at r + 0.5.
      const double crossing = r - 0.5 + (0.5 - before) / (t - before);
      if (std::abs(crossing - y) < best_gap) best = crossing, best_gap = std::abs(crossing - y);
    }
    before = t;
  }
  return best;
}

// Scratch images of one extraction (work size; `_h` at half of it).
struct Workspace {
  cv::Mat reduced, small, steps, sky, bins, steps_h, sky_h, persistent, unary, deviation, darker, clean;
  std::vector<uint16_t> row_sums, line_left, line_right;
  std::vector<uint8_t> line_runs;
  LabPlanes lab, lab_h;  // transposed
  EdgePenalty pen, pen_h;
  std::vector<float> acc, sample, top_reward;
  RefineStrips refine;
};

// How far terrain comes out of the sky's colour below a boundary: the
// median, over the columns with a row (`y`, full-size rows; sx, sy: work
// pixels per full-size pixel), of the colour distance from the sky just
// above (rows 3-8 over the boundary, per 1024 columns) to the terrain
// kFogRampFarRows below, less that to the terrain kFogRampNearRows below (3-row
// means). Under a boundary into fog the terrain comes out of it row by row,
// nearer and less veiled; under a hazy far ridge it stays about as faint as
// at its edge. Infinity when under a quarter of the columns can be read
// (a boundary at the image's foot: nothing tells it from fog).
double FogRamp(const LabPlanes& lab_t, const std::vector<double>& y, double sx, double sy) {
  const int ww = lab_t.Rows(), wh = lab_t.Cols();
  const double per = ww / 1024.0;
  const int sky0 = std::max(1, static_cast<int>(std::lround(8 * per))),
            sky1 = std::max(1, static_cast<int>(std::lround(3 * per)));
  const int near = std::max(1, static_cast<int>(std::lround(kFogRampNearRows * per)));
  const int far = std::max(near + 2, static_cast<int>(std::lround(kFogRampFarRows * per)));
  std::vector<double> ramps;
  int rows_given = 0;
  auto mean = [&](int c, int r0, int r1, float out[3]) {  // rows [r0, r1)
    const float *l = lab_t.l.ptr<float>(c), *a = lab_t.a.ptr<float>(c), *b = lab_t.b.ptr<float>(c);
    out[0] = out[1] = out[2] = 0;
    for (int r = r0; r < r1; ++r) out[0] += l[r], out[1] += a[r], out[2] += b[r];
    for (int k = 0; k < 3; ++k) out[k] /= static_cast<float>(r1 - r0);
  };
  auto distance = [](const float p[3], const float q[3]) {
    return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
  };
  for (size_t x = 0; x < y.size(); ++x) {
    if (!std::isfinite(y[x])) continue;
    ++rows_given;
    const int c = std::clamp(static_cast<int>(std::lround((x + 0.5) * sx - 0.5)), 0, ww - 1);
    const int r = static_cast<int>(std::lround(y[x] * sy));
    if (r - sky0 < 0 || r + far + 2 > wh) continue;
    float sky[3], at_near[3], at_far[3];
    mean(c, r - sky0, r - sky1 + 1, sky);
    mean(c, r + near - 1, r + near + 2, at_near);
    mean(c, r + far - 1, r + far + 2, at_far);
    ramps.push_back(distance(at_far, sky) - distance(at_near, sky));
  }
  if (4 * ramps.size() < static_cast<size_t>(rows_given) || ramps.empty()) return INFINITY;
  return Quantile(ramps, 0.5);
}

// Whether the image carries no colour (a grey or infrared camera, a grey
// copy): 99% of a sample of its pixels within kMonochromeChroma of neutral.
bool Monochrome(const LabPlanes& lab, std::vector<float>& chroma) {
  constexpr int kStride = 4;
  chroma.clear();
  for (int c = 0; c < lab.Rows(); c += kStride) {
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    for (int r = 0; r < lab.Cols(); r += kStride) chroma.push_back(std::hypot(a[r], b[r]));
  }
  if (chroma.empty()) return false;
  const auto p99 = chroma.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(chroma.size() - 1));
  std::nth_element(chroma.begin(), p99, chroma.end());
  return *p99 < kMonochromeChroma;
}

// The factor that stretches the photo's lightness span (L* from its
// kLightnessSpanLow to its kLightnessSpanHigh quantile, every 4th pixel of
// the work image across and down) over the whole scale of 100: 1 for a
// photo that spans it, at most kMaxLightnessStretch. Measured over the
// whole of the 13 real photos: about 1.05-2.7 (the hazy CG05 evenings 2.5
// and 2.7, the AK01b snowfields under haze 1.45-1.8).
double LightnessStretch(const LabPlanes& lab, std::vector<float>& ls) {
  constexpr int kStride = 4;
  ls.clear();
  for (int c = 0; c < lab.Rows(); c += kStride) {
    const float* l = lab.l.ptr<float>(c);
    for (int r = 0; r < lab.Cols(); r += kStride) ls.push_back(l[r]);
  }
  if (ls.size() < 2) return 1.0;
  auto at = [&](double q) {
    const auto it = ls.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(ls.size() - 1));
    std::nth_element(ls.begin(), it, ls.end());
    return static_cast<double>(*it);
  };
  const double high = at(kLightnessSpanHigh), low = at(kLightnessSpanLow);
  return std::clamp(100.0 / std::max(1.0, high - low), 1.0, kMaxLightnessStretch);
}

// The b* below which a pixel is saturated blue, sky and never terrain: at
// dawn, dusk or under a blue white balance the whole frame is blue, the
// ground too (its median b* in the bottom third, usually terrain, is then
// -15 to -30, against -8 to +25 otherwise: glacier ice is bluish), and a
// far ridge can be bluer than the sky over it. The threshold moves down by
// the cast beyond the usual. The median is read from every 4th pixel across
// and down (a video frame pays for it every time).
float DeepBlueB(const LabPlanes& lab, std::vector<float>& bs) {
  constexpr int kStride = 4;
  const int w = lab.Rows(), h = lab.Cols();
  bs.clear();
  for (int c = 0; c < w; c += kStride) {
    const float* b = lab.b.ptr<float>(c);
    for (int r = 2 * h / 3; r < h; r += kStride) bs.push_back(b[r]);
  }
  if (bs.empty()) return kDeepBlueB;
  std::nth_element(bs.begin(), bs.begin() + bs.size() / 2, bs.end());
  return kDeepBlueB + std::min(0.0f, bs[bs.size() / 2] - kNormalCastB);
}

// A photo more than a stop underexposed, brightened: when the bright end
// of its luma (the 99.5th percentile, read from every 4th pixel across and
// down) lies below half kExposureTarget in linear light, the image is
// scaled so that it reaches kExposureTarget (at most kMaxExposureGain
// times). The extraction's colour steps and thresholds are in delta E, and
// a photo 1.7 stops under (dusk, a webcam's exposure set by the snow) has
// every step a third smaller. In the 2.2-gamma model the gain is a scale of
// the 8-bit values by gain^(1/2.2) (`scale`, 1 when left alone), clipped. A
// photo nearer the target is left as it is: brightening those (the real
// photos' bright ends lie at 0.27-0.97) traded registrations on their
// changed copies (cool and soft ones lost 4, noisy and vignetted ones
// gained 2) and saturated a hazy blue mountain into "deep blue" sky.
cv::Mat Exposed(const cv::Mat& bgr, double& scale) {
  constexpr int kStride = 4;
  std::array<int, 256> hist{};
  int n = 0;
  for (int r = 0; r < bgr.rows; r += kStride) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(r);
    for (int c = 0; c < bgr.cols; c += kStride, ++n) ++hist[(29 * p[c][0] + 150 * p[c][1] + 77 * p[c][2] + 128) >> 8];
  }
  int k = 255, above = hist[255];  // k: the 99.5th percentile, above: the samples at k or brighter
  while (k > 0 && above <= n / 200) above += hist[--k];
  const double linear = std::pow((k + 0.5) / 255.0, 2.2);
  scale = 1.0;
  if (linear >= 0.5 * kExposureTarget) return bgr;
  scale = std::pow(std::min(kMaxExposureGain, kExposureTarget / linear), 1.0 / 2.2);
  cv::Mat out;
  bgr.convertTo(out, -1, scale);
  return out;
}

// The photo with its lens's vignetting divided out where the corners lose
// more than a stop (EstimateVignetting): a wide lens wide open or a cheap
// webcam's darkens the sky in the top corners and with it the steps of
// hazy ridges there. Measured (corner stops): the 13 real photos as taken
// and their darkened, brightened, noisy, soft, tinted and veiled copies
// 0.0 to -0.6 (their cameras' own fall-off), their turned copies to -0.6,
// the 28 rendered scenes -0.1 to 0; the photos under cos^4 vignetting
// (scripts/eval_real.py photometric, -2.2 stops at the corners) -1.5 to
// -2.4.
cv::Mat Flattened(const cv::Mat& bgr) {
  const Vignetting v = EstimateVignetting(bgr);
  if (!(v.CornerStops() < kVignettedCornerStops)) return bgr;
  return Devignetted(bgr, v);
}

// The photo smoothed, edges kept, when its pixel noise is that of a high
// ISO, a small sensor or a dim webcam frame (skyline_detail::NoiseSigma
// above kNoisySigma): the search reads steps of a few delta E against the
// sky's noise, which such noise buries. A bilateral filter (OpenCV's)
// averages each pixel with its neighbours within kDenoiseDiameter whose
// colours lie within a few noise sigmas, so a ridge's step of many sigmas
// stays sharp. Photos as cameras save them keep their pixels: measured,
// the 13 real photos 0.07-1.6, the 28 rendered scenes 0.3-1.5, the real
// photos' darkened, brightened, veiled and quality 30-50 copies 0.01-2.4;
// with noise of sigma 6 (of 255) per channel added, 4.5-5.4. Those noisy
// copies (scripts/eval_real.py photometric): 58.1% -> 65.4% of the traced
// columns within 2 px (given 88.0% -> 90.3%; 80.6% as taken), registered
// 8 of 13 either way, no false registration among their 91 wrong probes.
// A 5 x 5 median or two passes of this filter read fewer columns, OpenCV's
// non-local means a few more correctly for 100 times the time.
cv::Mat Denoised(const cv::Mat& bgr) {
  const double sigma = skyline_detail::NoiseSigma(bgr);
  if (!(sigma > kNoisySigma)) return bgr;
  cv::Mat out;
  cv::bilateralFilter(bgr, out, kDenoiseDiameter, kDenoiseColour * sigma, kDenoiseSpace);
  return out;
}

// A skyline's second candidates cleared when none is left (no y_alt: one
// candidate per column).
void DropEmptyAlt(Skyline& s) {
  if (std::none_of(s.y_alt.begin(), s.y_alt.end(), [](double v) { return std::isfinite(v); })) s.y_alt.clear();
}

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

// An overlay band along the top or bottom edge (a webcam's timestamp
// strip): rows of one flat colour across the width (at least half of each
// row within kBandTolerance of the edge row's median colour), carrying text
// (pixels far from that colour), ending in a straight edge (the next rows
// depart from it across the width). Read as scene, a black strip over the
// sky passes for a night sky above a pale "terrain" and its lower edge for
// the skyline (the real photos with a 28-row strip: 12 -> 2 of 13
// registered). Returns the rows to leave out at that edge (0: none): the
// band and a JPEG block below it (left in, the ringing's one darker row
// over the sky nulled CG05_20050811_130000's whole skyline).
constexpr int kBandTolerance = 4;         // levels per channel: JPEG's noise on a flat strip
constexpr double kBandRowShare = 0.5;     // text covers less of a band's row
constexpr double kBandFirstRowShare = 0.6;
constexpr int kTextLevels = 60;           // a text pixel departs this far from the band's colour
constexpr double kTextShare = 0.003;      // of the band's pixels at least
constexpr double kEdgeRowShare = 0.3;     // rows after the band: at most this share still its colour
constexpr int kBandEdgeRows = 8;  // a JPEG block: its ringing below the strip darkens the first sky rows

int OverlayBandRows(const cv::Mat& bgr, bool top) {
  const int h = bgr.rows, w = bgr.cols;
  const int max_rows = h / 5, min_rows = std::max(4, h / 150);
  if (max_rows < min_rows + 3 || w < 16) return 0;
  auto row_at = [&](int i) { return bgr.ptr<cv::Vec3b>(top ? i : h - 1 - i); };
  cv::Vec3b mode;
  {
    const cv::Vec3b* r = row_at(0);
    for (int k = 0; k < 3; ++k) {
      std::array<int, 256> hist{};
      for (int x = 0; x < w; ++x) ++hist[r[x][k]];
      int acc = 0, v = 0;
      while (acc + hist[v] <= w / 2) acc += hist[v++];
      mode[k] = static_cast<uchar>(v);
    }
  }
  auto near = [&](const cv::Vec3b& p, int tol) {
    return std::abs(p[0] - mode[0]) <= tol && std::abs(p[1] - mode[1]) <= tol && std::abs(p[2] - mode[2]) <= tol;
  };
  auto share_near = [&](int i) {
    const cv::Vec3b* r = row_at(i);
    int n = 0;
    for (int x = 0; x < w; ++x) n += near(r[x], kBandTolerance);
    return static_cast<double>(n) / w;
  };
  if (share_near(0) < kBandFirstRowShare) return 0;
  int rows = 0;
  long text = 0;
  while (rows < max_rows && share_near(rows) >= kBandRowShare) {
    const cv::Vec3b* r = row_at(rows);
    for (int x = 0; x < w; ++x) text += !near(r[x], kTextLevels);
    ++rows;
  }
  if (rows < min_rows || rows >= max_rows || text < kTextShare * rows * w) return 0;
  // The row right after the band may be its blurred edge; the next ones must depart.
  for (int i = rows + 1; i <= std::min(h - 1, rows + kBandEdgeRows); ++i)
    if (share_near(i) > kEdgeRowShare) return 0;
  return rows + kBandEdgeRows;
}

}  // namespace

int ExtractionReduction(int cols, int rows) {
  if (cols < kExtractWidth * 3 / 2) return 1;
  int k = std::min(kMaxBoxFactor, static_cast<int>(std::lround(static_cast<double>(cols) / kExtractWidth)));
  while (k > 1 && rows / k < 8) --k;
  return k;
}

cv::Mat BlockMeans(const cv::Mat& bgr, int k) {
  if (bgr.type() != CV_8UC3 || k < 2 || k > kMaxBoxFactor || bgr.rows < k || bgr.cols < k)
    throw InvalidArgument("BlockMeans: an 8-bit BGR image at least k x k and k in [2, 257]");
  cv::Mat out;
  std::vector<uint16_t> sums;
  BoxReduce(bgr, k, sums, out);
  return out;
}

void SkylineOptions::Check() const {
  if (roll_hint_deg && !(std::abs(*roll_hint_deg) <= 45.0)) ThrowField("SkylineOptions::roll_hint_deg", *roll_hint_deg, "|roll| <= 45");
  if (max_work_width_px < 64) ThrowField("SkylineOptions::max_work_width_px", max_work_width_px, ">= 64");
  if (!(smoothness > 0.0)) ThrowField("SkylineOptions::smoothness", smoothness, "> 0");
  if (!(edge_weight >= 0.0)) ThrowField("SkylineOptions::edge_weight", edge_weight, ">= 0");
  if (!(min_contrast >= 0.0)) ThrowField("SkylineOptions::min_contrast", min_contrast, ">= 0");
  if (!(min_contrast_sigmas >= 0.0)) ThrowField("SkylineOptions::min_contrast_sigmas", min_contrast_sigmas, ">= 0");
  if (!(faint_contrast_share > 0.0 && faint_contrast_share <= 1.0))
    ThrowField("SkylineOptions::faint_contrast_share", faint_contrast_share, "in (0, 1]");
  if (!(fog_contrast >= 0.0)) ThrowField("SkylineOptions::fog_contrast", fog_contrast, ">= 0");
  if (!(fog_max_chroma >= 0.0)) ThrowField("SkylineOptions::fog_max_chroma", fog_max_chroma, ">= 0");
}

int Skyline::VisibleCount() const {
  return static_cast<int>(std::count_if(y.begin(), y.end(), [](double v) { return std::isfinite(v); }));
}

namespace {

// ExtractSkyline on an image with no overlay bands (checked by the caller),
// its 8-bit values scaled by `exposure` (Exposed) from the photo's. The sky
// model whose departures veto sky (the first fit) has a robust scale of at
// least `sky_floor` (delta E); the refit that RaiseToSkyModelDeparture reads
// keeps kSkyModelFloor.
// `stretched_rows`, when given, receives the rows read with the least clear
// step judged over the photo's lightness span (see the refinement below), or
// is left empty where that reading is the one returned (a photo spanning the
// whole scale, or no skyline).
Skyline ExtractSceneSkyline(const cv::Mat& image, const SkylineOptions& options, double exposure,
                            float sky_floor = kSkyModelFloor, std::vector<double>* stretched_rows = nullptr) {
  Skyline out;
  out.width = image.cols;
  out.height = image.rows;
  out.y.assign(image.cols, NAN);
  out.confidence.assign(image.cols, 0.0);
  if (image.rows < 8 || image.cols < 8) return out;

  const cv::Mat bgr = ToBgr(image);
  if (const int k = ExtractionReduction(bgr.cols, bgr.rows); k >= 2) {
    const cv::Mat reduced = BlockMeans(bgr, k);
    std::vector<double> reduced_rows;
    Skyline up =
        MappedUp(ExtractSceneSkyline(reduced, options, exposure, sky_floor, stretched_rows ? &reduced_rows : nullptr),
                 k, image.cols, image.rows);
    if (stretched_rows && !reduced_rows.empty()) {
      Skyline rows;
      rows.width = reduced.cols, rows.height = reduced.rows;
      rows.y = std::move(reduced_rows);
      rows.confidence.assign(reduced.cols, 0.0);
      *stretched_rows = MappedUp(rows, k, image.cols, image.rows).y;
      for (int x = 0; x < image.cols; ++x) (*stretched_rows)[x] = PolishedRow(bgr, k, x, (*stretched_rows)[x]);
    }
    // At full size to within a fraction of a pixel: the edge each column
    // was read at, and its raise to a fainter ridge above where that raise
    // is within a reduced row (a row the edge half fills departs from the
    // sky's colour: which part of it is terrain shows only at full size);
    // a raise further up keeps its mapped row.
    for (int x = 0; x < up.width; ++x) {
      const double alt = up.Alt(x);
      if (!std::isfinite(alt) || std::abs(alt - up.y[x]) <= k) up.y[x] = PolishedRow(bgr, k, x, up.y[x]);
      if (std::isfinite(alt)) up.y_alt[x] = PolishedRow(bgr, k, x, alt);
    }
    return up;
  }

  // Search at a bounded width.
  const double scale = std::min(1.0, static_cast<double>(options.max_work_width_px) / image.cols);
  // Scratch images kept per thread: a video's frames reuse them instead of
  // faulting in ~10 MB of fresh pages per frame (a third of the time).
  thread_local Workspace ws;
  cv::Mat small;
  double sx = 1.0, sy = 1.0;  // work-image pixels per full-size pixel, across and down
  if (scale < 1.0) {
    // Area averaging by a whole factor first (cv::resize's general area
    // path took 30 ms for 4000 x 3000), then to the work size. Both ways of
    // the whole-factor step give the rounded block means and drop the last
    // < k rows and columns; OpenCV's 2 x 2 one is the faster at k = 2.
    int k = static_cast<int>(1.0 / scale);
    if (bgr.rows / k < 8) k = 1;  // a thin strip: straight to the work size
    cv::Mat source = bgr;
    if (k > 2 && k <= kMaxBoxFactor) {
      BoxReduce(bgr, k, ws.row_sums, ws.reduced);
      source = ws.reduced;
    } else if (k >= 2) {
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
  const LabPlanes& work_t = ws.lab;
  LabConverter::Instance().ConvertTransposed(small, ws.lab);
  // Cables across the sky erased before any boundary is sought (the
  // topmost clear edge took the higher cable for the skyline).
  EraseThinLines(ws.lab, ws.line_runs, ws.line_left, ws.line_right);
  const int ww = work_t.Rows(), wh = work_t.Cols();

  const double roll_rad = DegToRad(options.roll_hint_deg.value_or(0.0));
  const double slope = -std::tan(roll_rad);  // positive roll: the skyline rises to the right
  const float deep_blue_b = DeepBlueB(work_t, ws.sample);
  BoundarySteps(work_t, deep_blue_b, ws.steps);
  // Pass 1 only gives the first boundary that pass 2 learns the colours of
  // sky and ground from: at half the work size (a quarter of the time).
  std::vector<int> boundary(ww);
  float top_sky_l = 0.0f;  // the top band's median lightness
  {
    Halve(work_t, ws.lab_h);
    BoundarySteps(ws.lab_h, deep_blue_b, ws.steps_h);
    top_sky_l = SkyScoreFromTopBand(ws.lab_h, deep_blue_b, ws.sky_h);
    EdgeAbovePenalty(ws.steps_h, ws.sky_h, ws.lab_h, ws.pen_h);
    TopEdgeReward(ws.lab_h, ws.sky_h, top_sky_l, ws.top_reward);
    const std::vector<int> half = SolveBoundary(ws.sky_h, ws.steps_h, ws.pen_h, options.smoothness,
                                                options.edge_weight, slope, ws.acc, &ws.top_reward);
    for (int c = 0; c < ww; ++c)
      boundary[c] = std::min(wh, 2 * half[std::min(c / 2, static_cast<int>(half.size()) - 1)]);
  }
  // The sky model, fitted above the higher of the first boundary and the
  // topmost clear edge (pass 1 takes white snow for sky; the topmost edge
  // stops at it), vetoes sky where a pixel departs from the sky colour
  // expected at its place.
  PersistentSteps(work_t, kPersistentRows, deep_blue_b, ws.persistent);
  // The topmost edge's threshold scales with the noise of the whole top of
  // the image (cloud texture there raises it, so a cloud's soft edge is no
  // clear step); the contrast a column needs, with the sky's own noise
  // (measured over the whole top, a thin strip of sky over textured
  // terrain read as noisy and nulled up to half the columns: given 76% ->
  // 84% of the traced columns of the real photos cropped to 10 px of sky
  // above their highest point, 91.4% -> 92.4% uncropped; the rendered
  // scenes unchanged). The topmost edge's threshold from the sky's own
  // noise as well let cloud edges pass for terrain on the rendered scenes
  // (fuji_02: 79% -> 32% of its columns within 2 px).
  const TopNoise noise = MeasureTopNoise(ws.persistent, boundary);
  const float sky_noise = noise.sky;
  const std::vector<int> topmost = TopmostEdge(ws.persistent, noise.top, options.smoothness, slope, ws.unary, ws.acc);
  std::vector<int> fit_top(ww);
  for (int c = 0; c < ww; ++c) fit_top[c] = std::min(topmost[c], boundary[c]) - 3;
  SkyModel sky_model;
  sky_model.Fit(work_t, fit_top, 2, sky_floor);
  sky_model.Deviation(work_t, ws.deviation, &ws.darker);
  // Sky colours are learnt above the higher of the two boundaries, ground
  // colours below the lower: the band between (snow under the sky that
  // pass 1 took for sky, or clouds over sky that the topmost edge stopped
  // at) is decided by its context in the DP, not by its own colour.
  std::vector<int> sky_end(ww), ground_start(ww);
  for (int c = 0; c < ww; ++c) {
    sky_end[c] = std::min(boundary[c], topmost[c]) - 2;
    ground_start[c] = std::max(boundary[c], topmost[c]) + 3;
  }
  ws.clean.create(ww, wh, CV_8U);
  for (int c = 0; c < ww; ++c) {
    const float* dev = ws.deviation.ptr<float>(c);
    uint8_t* clean = ws.clean.ptr<uint8_t>(c);
    for (int r = 0; r < wh; ++r) clean[r] = dev[r] < kSkyModelClean ? 1 : 0;
  }
  // Under a floating cloud the histograms learn sky above the cloud only and
  // ground below the window's lowest first boundary only: the cloud's white
  // (the snow's) and the sky under it are neither's sample.
  const FloatingClouds clouds = FindFloatingClouds(work_t, sky_model, boundary);
  if (clouds.any)
    for (int c = 0; c < ww; ++c)
      if (clouds.sky_bottom[c] >= 0)
        sky_end[c] = std::min(sky_end[c], clouds.top[c] - 2),
        ground_start[c] = std::max(ground_start[c], clouds.lowest[c] + 3);
  SkyScoreFromHistograms(work_t, sky_end, ground_start, ws.clean, ws.bins, ws.sky);
  // Subtle departures from the sky colour expected at a pixel's place (more
  // than 3 robust sigmas, less than ~12 delta E: finer than the histogram's
  // bins) mark terrain: a hazy far ridge a few delta E off a pale sky.
  // Larger departures (clouds, snow, rock) are left to the histograms and
  // their context; saturated blue (a deep sky band) is always sky.
  VetoSubtleDepartures(ws.deviation, work_t, sky_model.scale(), deep_blue_b, ws.sky);
  // A floating cloud and the sky run under it are sky (measured on the real
  // photos with a cumulus in their widest sky, `eval_real.py --modes
  // sky-cloud`: 3 -> 10 of 13 registered, none of its ring of 468 wrong
  // positions; the photos as taken and the rendered scenes unchanged).
  for (int c = 0; c < ww; ++c) {
    float* sky_c = ws.sky.ptr<float>(c);
    for (int r = 0; r <= clouds.sky_bottom[c]; ++r) sky_c[r] = 1.0f;
  }
  EdgeAbovePenalty(ws.steps, ws.sky, work_t, ws.pen);
  TopEdgeReward(work_t, ws.sky, top_sky_l, ws.top_reward);
  boundary =
      SolveBoundary(ws.sky, ws.steps, ws.pen, options.smoothness, options.edge_weight, slope, ws.acc, &ws.top_reward);
  // The sky model again, above the boundary found: what RaiseToSkyModelDeparture reads.
  {
    for (int c = 0; c < ww; ++c) fit_top[c] = std::min(boundary[c], clouds.top[c]) - 3;  // not over a cloud
    sky_model.Fit(work_t, fit_top, 2, kSkyModelFloor);
  }

  // No sky: the region above the boundary must look like sky somewhere.
  {
    double sky_px = 0;
    for (int c = 0; c < ww; ++c) sky_px += boundary[c];
    if (sky_px < 0.01 * ww * wh) return out;
  }

  // Refine each full-size column around the (interpolated) boundary.
  const int window = static_cast<int>(std::ceil(1.0 / sy)) + 2;
  RefineStrips& strips = ws.refine;
  strips.count = 2 * window + 10;
  strips.first.assign(image.cols, RefineStrips::kNoStrip);
  std::vector<int> centres(image.cols);
  for (int x = 0; x < image.cols; ++x) {
    const double wc = std::clamp((x + 0.5) * sx - 0.5, 0.0, ww - 1.0);
    const int c0 = static_cast<int>(wc), c1 = std::min(c0 + 1, ww - 1);
    const double f = wc - c0;
    const double yb = ((1 - f) * boundary[c0] + f * boundary[c1]) / sy;
    if (yb <= 1.0 || yb >= image.rows - 1.0) continue;  // no boundary inside the image
    centres[x] = static_cast<int>(std::lround(yb));
    strips.first[x] = centres[x] - window - 5;
  }
  GatherStrips(bgr, strips);
  std::vector<ColumnFit> fits(image.cols);
  for (int x = 0; x < image.cols; ++x)
    if (strips.first[x] != RefineStrips::kNoStrip) fits[x] = RefineColumn(strips, x, image.rows, centres[x], window);
  const std::vector<uint8_t> occluded = FindOccluders(fits, image.rows);
  const int grow = std::max(3, image.cols / 128);  // the occluder's edges and the DP's way round it
  // The step noise of a smooth sky, a k-row mean difference: times
  // sqrt(k / 2) for the refinement's 3-row colours, roughly the pixel noise.
  // The floor is the photo's own (its 8-bit steps and JPEG blocks), so a
  // brightened photo's (Exposed) grows with it; the noise term already has.
  const double light_gain = std::pow(exposure, 2.2 / 3.0);  // delta E grows with the light as (exposure^2.2)^(1/3)
  const double min_contrast =
      std::max(options.min_contrast * light_gain, options.min_contrast_sigmas * 2.0 * sky_noise);
  std::vector<uint8_t> grown(occluded);
  for (int x = 0; x < image.cols; ++x)
    if (occluded[x])
      for (int k = std::max(0, x - grow); k <= std::min(image.cols - 1, x + grow); ++k) grown[k] = 1;
  // Everything after the refinement, from the columns' fits (the rows as
  // taken, or as read over the photo's lightness span with the colours and
  // contrasts as taken; ExtractSkyline keeps the columns the first gives).
  auto finish = [&](const std::vector<ColumnFit>& read) {
    Skyline done = out;
    for (int x = 0; x < image.cols; ++x) {
      const ColumnFit& f = read[x];
      if (!std::isfinite(f.y) || grown[x] || f.contrast < min_contrast) continue;
      done.y[x] = std::clamp(f.y, 0.0, static_cast<double>(image.rows));
      done.confidence[x] = std::clamp((f.contrast - min_contrast) / 20.0, 0.05, 1.0);
    }
    // Fog: where a horizon is seen against the sky, some of it stands out
    // clearly; when even the clearest tenth of the boundary is faint and the
    // boundary is soft, it is where near terrain fades into fog or whiteout,
    // not the horizon (a faint but sharp far ridge in haze stays).
    std::vector<double> contrasts, spreads, chromas, sky_ls;
    for (int x = 0; x < image.cols; ++x)
      if (std::isfinite(done.y[x]))
        contrasts.push_back(read[x].contrast), spreads.push_back(read[x].spread), chromas.push_back(read[x].sky_chroma),
            sky_ls.push_back(read[x].sky_l);
    // The sky's chroma as taken: brightening (Exposed, the 8-bit values times
    // `exposure`) raised chroma with the light, as (exposure^2.2)^(1/3), and a
    // grey dusk sky brightened 3 stops read as blue, so its fog went unjudged.
    if (!contrasts.empty() && Quantile(chromas, 0.5) / light_gain < options.fog_max_chroma) {
      const double clearest = Quantile(contrasts, 0.9), median_spread = Quantile(spreads, 0.5);
      // A fade spreads its colour change over more rows than an edge, which
      // the renderer or the lens smooths over ~2 rows per 1000 columns. A
      // monochrome image's sky has no chroma, so that cue tells nothing: its
      // fade must be clearly soft. Measured: grey copies of the hazy CG05
      // photos (a sharp ridge, 6-8 delta E, 3.3 rows) lost every column to
      // this test under the colour threshold; a grey 60-row fade spreads 5.3.
      const double soft = kFogSpreadRows * std::max(1.0, image.cols / 1024.0) *
                          (Monochrome(work_t, ws.sample) ? kMonochromeSoftFactor : 1.0);
      // The contrast an eye reads is relative to the light (an exposure 1.7
      // stops darker shrinks every delta E by a third): under a sky darker
      // than L* 84 the threshold shrinks with (L* + 16). Measured: a copy of
      // AK01b_20090827 darkened 1.7 stops (sky L* 30, clearest tenth 17.1)
      // or under a grey veil (L* 64, 17.9) was nulled whole; the rendered
      // fog scene's white sky (L* 92, 15.8) stays fog.
      const double sky_l = Quantile(sky_ls, 0.5);
      const double fog_contrast = options.fog_contrast * std::min(1.0, (sky_l + 16.0) / kFogReferenceLightness);
      // A faint soft boundary is fog only where the terrain comes out of it
      // below (FogRamp). Measured: the rendered fog scene's grass comes out by
      // 19.9 delta E (1.1 times its fog_contrast of 18), this module's
      // synthetic 60-row fades by 0.44-0.65 times theirs; copies of the real
      // photos under a grey veil or an overcast sky's light, whose skyline any
      // eye sees, by 0.6-1.9 delta E (0.04-0.13 times theirs): 9 of 39 copies
      // under 50-60% grey or an overcast light and 2 of the 104 photometric
      // copies (docs/MEASUREMENTS.md, "A grey veil is not fog") were nulled whole. The noisy
      // and vignetted copies of CG05_20050811_190000, whose boundary lies on
      // the glacier front in part, read 0.41 and 0.45 but pass the contrast.
      if (clearest < fog_contrast && median_spread > soft &&
          FogRamp(work_t, done.y, sx, sy) > kFogRampShare * fog_contrast) {
        std::fill(done.y.begin(), done.y.end(), NAN);
        std::fill(done.confidence.begin(), done.confidence.end(), 0.0);
        return done;
      }
    }
    // Fainter columns that continue clear ones, after the fog test (which
    // reads the clear columns only).
    ContinueFaintColumns(read, grown, options.faint_contrast_share * min_contrast,
                         kFaintMaxJumpPx * std::max(1.0, image.cols / 1024.0), image.rows, done);
    // A hazy far ridge's top taken for sky: the boundary up to where the sky ends.
    skyline_detail::RaiseToSkyEnd(bgr, grown, done.y);
    // A far ridge in haze above a clearer near one: the boundary up to where the sky ends.
    skyline_detail::RaiseToSkyModelDeparture(bgr, sky_model, sx, sy, deep_blue_b, grown, done.y, done.y_alt);
    // A column dipping below its neighbours onto an inner edge: up to the faint ridge above it.
    // Not from the columns raised to a departure from the sky model on both
    // sides (a sunset's glow raised over a notch would lift the notch; on one
    // side they count: real photos 80.6% -> 80.8% of the traced columns
    // within 2 px, rendered 97.3% -> 97.4%); those raised to the sky's end
    // count (measured: without them the real photos' gain is lost, 99
    // columns mended -> 7).
    skyline_detail::RaiseDips(bgr, grown, done.y, done.y_alt);
    // A ridge's top fainter than its edge lower down (a dark crest, a bright
    // rim, haze on the upper slope): the boundary up to where the lightness
    // first departs from the sky's (measured on the real photos: 76.3% ->
    // 80.1% of the traced columns within 2 px; rendered 97.3% -> 97.4%). The
    // matching reads the edge it was raised from (y_alt): matching the raised
    // boundary against the 100 m DEM, whose flattened peaks lie lower still,
    // left AK01b_20080811 ambiguous (cost ratio 1.40 -> 1.39) and 0 of its 7
    // perturbed runs registered instead of 5.
    {
      const std::vector<double> before = done.y;
      skyline_detail::RaiseToFirstDeparture(bgr, grown, done.y);
      done.y_alt.resize(done.y.size(), NAN);
      for (size_t x = 0; x < done.y.size(); ++x)
        if (done.y[x] != before[x] && !std::isfinite(done.y_alt[x])) done.y_alt[x] = before[x];
    }
    DropEmptyAlt(done);
    return done;
  };
  Skyline taken = finish(fits);
  // Each column's row read again with its least clear step judged over the
  // photo's own lightness span (LightnessStretch): a hazy photo's lightness
  // spans half the scale or less, and the faint step at a snow ridge's top,
  // half the snow's edge below it but under the 5 delta E of a clear step as
  // taken, stands out to an eye adapted to that span. Only the rows move:
  // whether a column is given, and the fog test, read the colours as taken.
  // The matching reads the skyline as taken (ExtractSkyline keeps it as
  // y_alt where the rows differ), so no registration changes. Measured
  // (docs/MEASUREMENTS.md, "Lightness read over the photo's span"): the
  // real photos' traced columns within 2 px 80.8% -> 81.4%, the rendered
  // scenes 97.4% as before. Stretching the lightness itself (every step and
  // colour of the refinement) read 82.3% but put a thin pale sky's boundary
  // on the texture of the snow under it (655 -> 584 of 768 columns within
  // 2 px, ThinPaleSkyOverSnowToTheBottomKeepsItsColumns).
  if (const double stretch = stretched_rows ? LightnessStretch(work_t, ws.sample) : 1.0; stretch > 1.0) {
    std::vector<ColumnFit> moved = fits;
    int changed = 0;
    for (int x = 0; x < image.cols; ++x)
      if (strips.first[x] != RefineStrips::kNoStrip && std::isfinite(fits[x].y))
        if (const double y = RefineColumn(strips, x, image.rows, centres[x], window, static_cast<float>(stretch)).y;
            std::isfinite(y) && y != fits[x].y)
          moved[x].y = y, ++changed;
    if (changed > 0) *stretched_rows = finish(moved).y;
  }
  return taken;
}

}  // namespace

Skyline ExtractSkyline(const cv::Mat& image, const SkylineOptions& options) {
  options.Check();
  if (image.empty() || image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4))
    throw InvalidArgument("skyline: the image must be a non-empty 8-bit grey, BGR or BGRA image");
  if (image.rows < 8 || image.cols < 8) return ExtractSceneSkyline(image, options, 1.0);
  double exposure = 1.0;
  cv::Mat bgr = Exposed(Flattened(ToBgr(image)), exposure);
  // A photo wider than 1.5 times the extraction's width is read as means of
  // blocks of k x k pixels (ExtractionReduction), whose noise is that over k
  // (sensor noise of sigma 6 per channel: luma 4 at full size, 2 in 2 x 2
  // means): only a photo read pixel for pixel is smoothed.
  if (ExtractionReduction(bgr.cols, bgr.rows) == 1) bgr = Denoised(bgr);
  // A timestamp strip along the top or bottom edge is not scene: the
  // skyline is read between them, in the photo's rows.
  const int top = OverlayBandRows(bgr, true), bottom = OverlayBandRows(bgr, false);
  const bool banded = (top > 0 || bottom > 0) && bgr.rows - top - bottom >= 8;
  const cv::Mat scene = banded ? bgr.rowRange(top, bgr.rows - bottom).clone() : bgr;
  // The skyline as taken, and the rows read with the least clear step judged
  // over the photo's lightness span (`stretched`, empty where that reading
  // is the same).
  auto extract = [&](float sky_floor, std::vector<double>& stretched) {
    Skyline s = ExtractSceneSkyline(scene, options, exposure, sky_floor, &stretched);
    if (banded) {
      s.height = image.rows;
      s.overlay_top_rows = top, s.overlay_bottom_rows = bottom;
      for (double& v : s.y) v += top;
      for (double& v : s.y_alt) v += top;
      for (double& v : stretched) v += top;
    }
    return s;
  };
  std::vector<double> stretched;
  Skyline s = extract(kSkyModelFloor, stretched);
  // A JPEG's smooth sky comes in 8-row blocks, its gradient in steps of a
  // few delta E between them (chroma steps at quality 30-50), and the sky
  // model, fitted where the blocks are flat, takes the sky below such a
  // step for a hazy ridge: the skyline then runs along one grid row for
  // hundreds of columns. A terrain boundary does not (measured: the 13
  // real photos' longest run 24 columns, the rendered scenes' 47; their
  // quality-30 copies 106-364; a rendered video frame 640 px wide, 60: a
  // level far ridge on a grid row). Those columns are read again with the
  // sky model's scale at least kBlockSkyFloor, which a clear ridge passes
  // as before (that frame's 60 columns stay) and the sky under a block's
  // step no longer departs from (the real photos' quality-30 copies: 51.7%
  // -> 63.6% of the traced columns within 2 px, registered 7 -> 9 of 13;
  // quality 50: 9 -> 10). Not the whole photo: that floor is too loose
  // for the faint ridges of photos as taken (CG05_20050811_190000 loses
  // them all, the photos 80.6% -> 74.0%).
  const int min_run = skyline_detail::ColumnsPer1024(kGridRunColumns, image.cols, 40);
  if (const std::vector<uint8_t> long_runs = skyline_detail::GridRunColumns(s.y, kJpegBlockRows, kGridRowSlack, min_run);
      std::find(long_runs.begin(), long_runs.end(), 1) != long_runs.end()) {
    // Once one long run shows it, shorter ones on other grid rows are the
    // same steps (the boundary stepping from one block row to the next).
    const std::vector<uint8_t> runs = skyline_detail::GridRunColumns(
        s.y, kJpegBlockRows, kGridRowSlack,
        skyline_detail::ColumnsPer1024(kGridShortRunColumns, image.cols, 12));
    std::vector<double> stretched_again;
    const Skyline again = extract(kBlockSkyFloor, stretched_again);
    s.y_alt.resize(s.width, NAN);
    if (!stretched.empty() || !stretched_again.empty()) stretched.resize(s.width, NAN);
    for (int x = 0; x < s.width; ++x)
      if (runs[x]) {
        s.y[x] = again.y[x], s.confidence[x] = again.confidence[x], s.y_alt[x] = again.Alt(x);
        if (!stretched.empty()) stretched[x] = stretched_again.empty() ? NAN : stretched_again[x];
      }
    DropEmptyAlt(s);
  }
  // A short stretch of columns between long gaps is no part of a ridge:
  // snow patches in rock that reaches the top of the frame (or a timestamp
  // strip), whose top rows pass for sky, or a glacier's front under a ridge
  // lost in haze. Measured over the real photos, their changed and
  // compressed copies and the rendered scenes: of the columns in such
  // stretches 501 lie more than 2 px off the traced horizon, 196 within it;
  // under a strip they gave AK10_20090803 a rival 54 deg off (its skyline
  // without them registers).
  {
    const std::vector<uint8_t> iso = skyline_detail::IsolatedRunColumns(
        s.y, skyline_detail::ColumnsPer1024(kIsolatedRunColumns, image.cols, 8),
        skyline_detail::ColumnsPer1024(kIsolatedGapColumns, image.cols, 5));
    for (int x = 0; x < s.width; ++x)
      if (iso[x]) {
        s.y[x] = NAN, s.confidence[x] = 0.0;
        if (x < static_cast<int>(s.y_alt.size())) s.y_alt[x] = NAN;
      }
    DropEmptyAlt(s);
  }
  // The rows read over the photo's lightness span are the skyline's; the
  // matching reads the skyline as taken (MatchY: its y_alt where it set
  // one, else its y), kept as y_alt wherever the two differ. Columns given
  // in one reading only keep the skyline as taken.
  if (!stretched.empty()) {
    s.y_alt.resize(s.width, NAN);
    for (int x = 0; x < s.width; ++x) {
      if (!std::isfinite(s.y[x]) || !std::isfinite(stretched[x])) continue;
      const double matched = s.MatchY(x);
      s.y[x] = stretched[x];
      s.y_alt[x] = stretched[x] == matched ? NAN : matched;
    }
    DropEmptyAlt(s);
  }
  return s;
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
