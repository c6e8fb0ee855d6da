// SPDX-License-Identifier: MIT
// Skyline extraction: the boundary between sky and terrain in a photo, one
// sub-pixel y per column, with a confidence, and null where the terrain
// horizon is not seen (trees or poles in front of it, fog, no sky).
// Paper, section 3.1 (Sobel edges scanned from the top, one point per column
// under continuity constraints); here solved globally by dynamic programming
// over columns with a colour model of sky and ground learnt from the image.
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace cv {
class Mat;
}

namespace horizonreg {

struct SkylineOptions {
  std::optional<double> roll_hint_deg;  // Inclinometer roll (conventions.h): tilts the search.
  int max_work_width_px = 512;          // Images are searched at most this wide, then refined at full size.
  double smoothness = 1.5;              // DP cost per pixel of jump between neighbouring columns.
  double edge_weight = 1.0;             // DP reward per unit of colour step (CIELAB delta E) at the boundary.
  // Columns whose sky/ground colours differ less are null: delta E, at
  // least min_contrast and min_contrast_sigmas times the sky's pixel noise
  // (read from the sky at the top of the image, above the first boundary:
  // a faint ridge in haze under a smooth sky stands clear of it, and a thin
  // strip of sky is not judged by the terrain's texture below it).
  double min_contrast = 2.5;
  double min_contrast_sigmas = 2.5;
  // A column down to this share of that contrast is kept when it continues
  // a kept column without a jump (hysteresis).
  double faint_contrast_share = 0.6;
  // Fog: all null when the sky above the boundary is white-grey (chroma
  // below fog_max_chroma), the clearest 10% of the boundary differ by less
  // than fog_contrast (delta E; under a sky darker than L* 84, that times
  // (L* + 16) / 100: contrast relative to the sky's lightness, as an eye
  // reads it) and the boundary is soft: terrain fading into fog, not a
  // horizon. A faint ridge under a blue sky is haze, kept. A monochrome
  // image (no chroma to read) needs a clearly softer boundary.
  double fog_contrast = 18.0;
  double fog_max_chroma = 8.0;
  void Check() const;                   // Throws InvalidArgument naming the field.
};

struct Skyline {
  int width = 0, height = 0;
  // Per column: y of the sky/terrain boundary in pixels (DESIGN.md image
  // coordinates: the first terrain pixel row r has its top edge at y = r),
  // NaN where the horizon is not visible.
  std::vector<double> y;
  std::vector<double> confidence;  // [0, 1] per column; 0 where y is NaN
  // Empty, or per column the clearer edge below y (NaN where there is
  // none) that y was raised from to the top of a faint far ridge, or of a
  // ridge whose uppermost rows are fainter than its edge lower down. The
  // matching reads it (MatchY): a coarse DEM flattens such ridges or lacks
  // them (measured on the real photos: matching the raised boundary cost 3
  // of 12 registrations, scoring each column by the better of the two cost
  // 1 and brought wrong positions nearer the ambiguity gate; matching the
  // first-departure raise cost 1).
  std::vector<double> y_alt;
  // Rows along the top and bottom edges that are no scene (a webcam's
  // timestamp strip and a JPEG block below it): the skyline was read
  // between them, and a re-read near a predicted horizon stays out of them.
  int overlay_top_rows = 0, overlay_bottom_rows = 0;
  double Alt(int x) const { return x >= 0 && x < static_cast<int>(y_alt.size()) ? y_alt[x] : NAN; }
  // The boundary the matching reads in column x: y_alt where set, else y.
  double MatchY(int x) const { return std::isfinite(Alt(x)) ? y_alt[x] : y[x]; }
  int VisibleCount() const;
};

// Extracts the skyline of an 8-bit image (1, 3 or 4 channels, OpenCV BGR
// order). A uniform, all-sky or all-ground image gives all-null output. An
// image more than a stop underexposed (its bright end, the 99.5th
// percentile of luma, under 0.21 in linear light) is brightened to 0.42
// first, at most 3 stops; min_contrast and fog_max_chroma then apply to it
// as it was taken. Where the skyline runs along one of a JPEG's 8-row block
// rows for 80 columns per 1024 or more (the codec's steps in a smooth sky,
// not terrain), the runs along block rows are read again under a looser
// sky model.
// Throws InvalidArgument for an empty image or bad options. Thread-safe;
// each thread keeps its scratch images (~10 MB at the default work width)
// for its next call, so a video's frames do not fault in fresh memory.
Skyline ExtractSkyline(const cv::Mat& image, const SkylineOptions& options);

// The whole factor by which ExtractSkyline reduces an image `cols` x `rows`
// before reading it (1: none): from 1.5 times 1024 columns on, the factor
// that brings the width nearest 1024 (at least 8 rows kept). The
// refinement's rows and thresholds are tuned at that width; a wider image's
// edges spread over more rows. Boundaries scale back by the factor exactly.
int ExtractionReduction(int cols, int rows);

// The mean of each k x k block of an 8-bit BGR image, rounded (the last
// < k rows and columns dropped: reduced pixel i covers full-size pixels
// k i .. k i + k - 1). k in [2, 257]; throws InvalidArgument otherwise.
cv::Mat BlockMeans(const cv::Mat& bgr, int k);

// The skyline read again where a registered pose predicts it: `predicted`
// is the DEM horizon projected at that pose (per column, NaN where none),
// which a coarse DEM flattens, so that the true skyline lies up to
// above_px[x] above it and up to below_px[x] below it (at most 40 rows in
// all per 1024 columns are read). A column whose extracted boundary lies
// below that window (the extractor stopped at a clearer edge under a hazy
// ridge) is read again, the column averaged with two neighbours on each
// side: from the top of the window down, the first row whose 16 rows above
// (less the one next to it, which a sloping edge half fills) are smooth sky
// (a quadratic per CIELAB channel, 90% of them within half the threshold),
// and from which the column departs from that fit by more than max(4
// robust sigmas, 3 delta E) in 80% of the rows down to the extracted
// boundary (6 to 12 of them: a thin cloud has sky under it), starts the
// terrain; the boundary is the half-way crossing from the fitted sky to
// the colour of the 3 rows below (rows scale with the width over 1024). A
// value read so more than 3 px (per 1024 columns) from the median of the 5
// columns on each side (a band of haze) is dropped. Every other column
// keeps its extracted value, null ones too (a tree, fog); y_alt is cleared.
// `image` is 8-bit BGR of the skyline's size; throws InvalidArgument
// otherwise. Columns with a negative or NaN window are left alone.
Skyline GuideSkyline(const cv::Mat& image, const Skyline& skyline, const std::vector<double>& predicted,
                     const std::vector<double>& above_px, const std::vector<double>& below_px);

// Draws the skyline over the image (coloured by confidence, null columns
// marked at the top edge) for inspection.
cv::Mat DrawSkylineDebug(const cv::Mat& image, const Skyline& skyline);

}  // namespace horizonreg
