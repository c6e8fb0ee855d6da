// SPDX-License-Identifier: MIT
// The skyline extractor's full-size stage (internal to the skyline module):
// each column's sub-pixel boundary near the one the search found at the work
// size, read from strips of the full-size image, and the columns where a tree
// or pole stands in front of the horizon.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "skyline/lab.h"
#include "skyline/sky_model.h"
#include "skyline/skyline.h"

namespace horizonreg::skyline_detail {

// One column's refined boundary and what the occluder and fog tests read.
struct ColumnFit {
  double y = NAN;
  double contrast = 0;      // delta E between the local sky and ground colours
  double ground_l = 0;      // lightness just below the boundary
  double ground_green = 0;  // -a* just below the boundary (positive = green)
  double spread = 0;        // contrast / the largest one-row step: about 1-2 rows for an edge, more for a fade
  double sky_chroma = 0;    // chroma (sqrt(a*^2 + b*^2)) just above the boundary
  double sky_l = 0;         // lightness just above the boundary
};

// Strips of the full-size image around the boundary, `count` rows from row
// first[x] in every column x, as CIELAB planes (strip x from index x * count),
// converted in one batch.
struct LabStrips {
  std::vector<uint8_t> bgr;
  std::vector<float> l, a, b;
  void Convert() {
    const int n = static_cast<int>(bgr.size() / 3);
    l.resize(n), a.resize(n), b.resize(n);
    LabConverter::Instance().Convert(bgr.data(), 3, n, l.data(), a.data(), b.data());
  }
  // The squared delta E between entries i and j, the lightness difference
  // times `gain`.
  float DistanceSq(int i, int j, float gain = 1.0f) const {
    const float dl = gain * (l[i] - l[j]), da = a[i] - a[j], db = b[i] - b[j];
    return dl * dl + da * da + db * db;
  }
};

// What the refinement reads: each column's strip (its own colours), and the
// same strip of the column averaged with kStepColumns neighbours on each
// side. The steps that choose the boundary row are read from the average
// (pixel noise in the sky would otherwise pass for the topmost clear step),
// the crossing and the colours from the column itself.
struct RefineStrips {
  int count = 0;
  std::vector<int> first;  // per column; kNoStrip where the boundary is outside the image
  LabStrips column, wide;
  std::vector<float> steps;  // RefineColumn's scratch
  std::vector<int> rows;
  static constexpr int kNoStrip = std::numeric_limits<int>::min();
};

// Where a colour crosses half way from sky to ground between rows r - 1 and
// r, for r from `from` to `to`: t(r) the colour's share of the way back to
// the sky (1 sky, 0 ground). NaN when it does not cross there.
template <typename Share>
double HalfWayCrossing(int from, int to, const Share& t) {
  for (int r = from; r <= to; ++r) {
    const float t0 = t(r - 1), t1 = t(r);
    if (t0 >= 0.5f && t1 < 0.5f) return (r - 0.5) + (t0 - 0.5) / (t0 - t1);
  }
  return NAN;
}

// Where the colour of planes l, a, b (row r at index r - first) crosses
// half way from `sky` to `ground` (CIELAB), between rows from - 1 and to as
// HalfWayCrossing reads them. NaN when it does not cross there or the two
// colours are (nearly) the same.
inline double ColourCrossing(const float* l, const float* a, const float* b, int first, const float* sky,
                             const float* ground, int from, int to) {
  const float d[3] = {sky[0] - ground[0], sky[1] - ground[1], sky[2] - ground[2]};
  const float dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (!(dd > 1e-6f)) return NAN;
  return HalfWayCrossing(from, to, [&](int r) {  // 1 sky, 0 ground
    const int i = r - first;
    return ((l[i] - ground[0]) * d[0] + (a[i] - ground[1]) * d[1] + (b[i] - ground[2]) * d[2]) / dd;
  });
}

// Per column x with a strip (first[x] != RefineStrips::kNoStrip): `count`
// rows from first[x] (rows outside the image repeat the edge row) of the
// column averaged with `half` neighbours on each side (fewer at the image's
// edges), rounded; BGR, column after column (strip x from 3 * x * count).
void AverageStrips(const cv::Mat& bgr, const std::vector<int>& first, int count, int half, std::vector<uint8_t>& out);

// Fills the strips: `count` rows from first[x] (rows outside the image
// repeat the edge row), and converts them.
void GatherStrips(const cv::Mat& bgr, RefineStrips& strips);

// Sub-pixel boundary of full-size column x (h rows) within `window` rows of
// row `centre`: where the colour crosses half way from the local sky colour
// to the local ground colour. The strip holds rows centre - window - 5 to
// centre + window + 4. The row is that of the topmost clear step (at least
// kTopStepShare of the strongest, and kTopStepMin delta E with the
// lightness difference times `lightness_gain`: see LightnessStretch in
// skyline.cc), else the strongest.
ColumnFit RefineColumn(RefineStrips& strips, int x, int h, int centre, int window, float lightness_gain = 1.0f);

// Raises each column's boundary to where the sky ends, when the boundary
// found lies a few rows inside the terrain: a hazy far ridge whose colour is
// a few delta E off the sky's (its snow tinted blue by the air) is taken for
// sky down to a clearer step below it. From the top of the search (20 rows
// above the boundary, scaled with the width over 1024) down, the first row
// where the column departs from a straight-line fit of the 16 rows above it
// (CIELAB, chroma weighted 0.4: JPEG blurs and blocks it) by more than
// max(4 robust sigmas of the fit, 3.5) is the sky's end, when
//  - the fitted rows are uniform (90% within half that threshold: no
//    edge, cloud or band among them),
//  - the departure holds in the next row and in 80% of the rows down to the
//    boundary (a ridge, not a ripple in the sky), and
//  - those rows (but the 2 next to the boundary, where a sloping edge
//    passes the neighbouring columns) have horizontal texture at least 3
//    times the fitted rows': the lightness difference between the
//    neighbouring columns and its second difference (rock and snow, not a
//    smooth band of sky or the gradient of a cloud), and
//  - it lies at least 4 rows above the boundary: one row is left between
//    it and the 2 edge rows to read the texture from (closer, the
//    refinement's crossing is as good).
// The boundary then lies half a row above that row. Columns flagged in
// `skip` and null ones are left alone.
void RaiseToSkyEnd(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y);

// Raises each column's boundary to where the lightness first departs from
// the sky's, up to 6 rows (at 1024 columns) above it: the top of a ridge
// whose uppermost rows are fainter than the edge the refinement chose lower
// down (a dark crest over bright snow, a bright rim over dark rock, haze
// thinning down the upper slope). The half-way crossing places such a
// boundary on the lower edge, 2-6 rows under the traced horizon of real
// photos. Per column (averaged with its two neighbours):
//  - the sky is a line in L* and one in b* through the 12 rows above the
//    search;
//  - a row departs when its L* is off the sky's line by more than 30% of the
//    contrast (the ground's departure 2-4 rows below the boundary, or a
//    band's on the way down when larger), 2 delta L and 6 robust sigmas of
//    the fitted rows;
//  - the boundary rises to where the departure crosses that threshold in
//    the topmost row from which every row down to the boundary departs,
//    when that is at least half a row higher and below the search's top row
//    (the boundary's own row may match the sky's lightness when it lies
//    half way from a darker crest to brighter ground).
// Lightness only: JPEG keeps the chroma at half resolution and blurs it
// over the edge (its ramp starts 2-3 rows above a rendered horizon's
// truth). A column whose rows down to the boundary include one more than
// 2 b* bluer than the fitted sky is left alone: the lines were fitted to
// a cloud over a band of blue sky. Columns flagged in `skip` and null ones
// are left alone.
void RaiseToFirstDeparture(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y);

// Raises each column's boundary to the top of a ridge that departs from the
// sky's expected colour, when the boundary found lies on a clearer edge
// lower down: a far ridge in haze a few delta E off a smooth sky (snow
// tinted blue by the air over a bright near range; 5-30 robust sigmas of a
// clear sky, yet a weaker step than the near ridge's). RaiseToSkyEnd's
// straight line of the rows just above stands in for the sky there; this
// reads the sky model fitted to the whole sky (`model`, on work planes of
// `work_per_px` work pixels per image pixel across and down), which a
// ridge of several rows does not bend. Per column (the column averaged
// with its two neighbours), from 20 rows above the boundary (scaled with
// the width over 1024) down, the first row that
//  - departs from the model by more than 4 of its robust sigmas (the
//    model's own, at least 1 delta E), as does the row below it,
//  - and from a straight line through the 16 rows above it (a smooth
//    gradient the model misses, as a sunset's glow near the horizon, stays
//    sky),
//  - is not saturated blue (b* above deep_blue_b: a deep band of sky), and
//  - is followed down to the boundary by departing rows (80% of them),
// starts the terrain, unless the rows above it depart from the model by
// more than half as much (median against median: the model does not fit
// the sky there) or the departure falls below half its peak before a
// boundary whose terrain departs twice that peak (sky between a band and
// the ridge; both end the column's search). Then the boundary moves to
// the half-way crossing from the model's sky colour to the ridge's (the
// mean of the 3 rows below), when that lies at least 3 rows (scaled
// likewise) above it (closer, the refinement's crossing of the clearer
// edge is as good). Columns flagged
// in `skip` and null ones are left alone.
// The boundary it moved from is kept in `alt` (sized like y, NaN where
// nothing moved).
void RaiseToSkyModelDeparture(const cv::Mat& bgr, const SkyModel& model, double work_per_px_x, double work_per_px_y,
                              float deep_blue_b, const std::vector<uint8_t>& skip, std::vector<double>& y,
                              std::vector<double>& alt);

// Raises a column that dips below its neighbours to the ridge above it,
// when its own column shows one: the DP and the refinement took the
// clearer inner edge (dark rock under a faint snow ridge in haze) where
// the neighbours found the ridge. Neighbours are read within 6 columns on
// each side per 1024 (at least 3). The columns raised before (finite in
// `alt`, as RaiseToSkyModelDeparture leaves it) count on one side only,
// the other side's top read from columns not raised: a sunset's glow
// raised on both sides of a notch would lift the notch, while a dip beside
// columns the sky model raised (AKJNC_20120813's columns 879-880) is lifted.
// A run of dips wider than the reach is not (its own columns are the
// lower side's top: AKJNC_20120813's 864-874 re-encoded at JPEG quality 95).
// A dip lies more
// than 2.5 rows (scaled with the width over 1024) below the lower of the
// two sides' highest boundaries, `top`. From 8 rows above `top`, a straight
// line through 6 rows of the column's sky; the first row from which 3 in a
// row depart from the line by more than max(3 delta E, 4 robust sigmas of
// its residuals) (JPEG's blocks in a smooth sky stay below 3), as do 80% of
// the rows down to 2 above the boundary, starts the terrain, when it lies
// no more than 2 rows above `top`. The boundary moves to the half-way
// crossing from the line's colour to the 3 rows below that row and the
// one it leaves is kept in `alt` (sized like y, or empty and then sized)
// unless that holds one already: the clearer edge a coarse DEM sees as
// well, which the matching reads (Skyline::MatchY), so registration is
// unchanged. A dip whose column shows no departure keeps its boundary (a
// notch). Three passes: a dip two or three columns wide closes from its
// sides. Columns flagged in `skip` and null ones are left alone.
void RaiseDips(const cv::Mat& bgr, const std::vector<uint8_t>& skip, std::vector<double>& y, std::vector<double>& alt);

// Hysteresis (as Canny's edges): a column too faint to stand alone (its
// contrast at least faint_contrast, under the clear columns' threshold)
// joins the skyline when it continues a kept neighbour without a jump of
// more than max_jump_px, column after column, from both sides. A hazy ridge
// under a smooth sky keeps a boundary of 1.5-2.5 delta E along hundreds of
// columns, each alone too faint to trust. Joined columns get confidence
// 0.05; columns flagged in `skip` stay null.
void ContinueFaintColumns(const std::vector<ColumnFit>& fits, const std::vector<uint8_t>& skip, double faint_contrast,
                          double max_jump_px, int image_rows, Skyline& out);

// 1 for the columns where an occluder (tree, pole) hides the horizon.
std::vector<uint8_t> FindOccluders(const std::vector<ColumnFit>& fits, int image_rows);

// The q-quantile (0..1) of a non-empty sample (reorders it).
double Quantile(std::vector<double>& v, double q);

// A column count given per 1024 columns, for an image `cols` wide: rounded,
// and at least `at_least` (thresholds tuned at the extraction width).
inline int ColumnsPer1024(double per_1024, int cols, int at_least) {
  return std::max(at_least, static_cast<int>(std::lround(per_1024 * cols / 1024.0)));
}

// The columns of runs, at least `min_run` long, in which y lies within
// `slack` rows of one and the same multiple of `grid` (a JPEG's block
// rows): 1 in those columns, 0 elsewhere (NaN breaks a run).
std::vector<uint8_t> GridRunColumns(const std::vector<double>& y, int grid, double slack, int min_run);

// The columns of isolated stretches: finite runs joined across gaps of
// fewer than `min_gap` nulls, spanning at most `max_run` columns (so with
// at least `min_gap` nulls on each side; a stretch touching the image's
// left or right edge is never isolated): 1 in their finite columns, 0
// elsewhere.
std::vector<uint8_t> IsolatedRunColumns(const std::vector<double>& y, int max_run, int min_gap);

// The standard deviation of an image's pixel noise, in 8-bit luma units
// (Immerkaer 1996, robustly): the luma convolved with the difference of two
// Laplacians (which a locally linear surface cancels; unit Gaussian noise
// comes out with deviation 6), the median of its magnitude over every
// second row, over 0.6745 * 6. Texture and edges lie in the upper tail.
double NoiseSigma(const cv::Mat& bgr);

}  // namespace horizonreg::skyline_detail
