// SPDX-License-Identifier: MIT
#include "skyline/refine.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "testing/pixel_noise.h"

namespace horizonreg::skyline_detail {
namespace {

constexpr int kW = 200, kH = 120, kTop = 60, kBoundary = 70;  // the hazy band: rows kTop .. kBoundary - 1

// A blue sky down to row kTop, then `band(x, y)` down to kBoundary, then snow.
template <typename Band>
cv::Mat Scene(Band band) {
  cv::Mat img(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      img.at<cv::Vec3b>(y, x) = y < kTop ? cv::Vec3b(185, 150 + y / 12, 118 + y / 12)
                                : y < kBoundary ? band(x, y)
                                                : cv::Vec3b(238, 236, 234);
  return img;
}

int CountAt(const std::vector<double>& y, double row) {
  int n = 0;
  for (double v : y) n += std::abs(v - row) <= 1.0;
  return n;
}

TEST(RaiseToSkyEnd, AHazyRidgeTakenForSkyIsGivenBack) {
  // Rock and snow tinted by the air: a few delta E off the sky, textured.
  const cv::Mat img = Scene([](int x, int y) {
    const int n = (x * 37 + y * 91 + x * y * 7) % 21 - 10;
    return cv::Vec3b(cv::saturate_cast<uchar>(170 + n), cv::saturate_cast<uchar>(160 + n),
                     cv::saturate_cast<uchar>(150 + n));
  });
  std::vector<double> y(kW, kBoundary);
  RaiseToSkyEnd(img, std::vector<uint8_t>(kW, 0), y);
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.9 * kW);
}

TEST(RaiseToSkyEnd, ASmoothCloudOrABoundaryAtTheSkysEndStays) {
  // A cloud's smooth gradient (it changes from column to column, its
  // second difference does not): not terrain.
  const cv::Mat cloud = Scene([](int x, int y) {
    const double v = 200 + 50 * std::sin(x / 8.0) + 2 * (y - kTop);
    return cv::Vec3b::all(cv::saturate_cast<uchar>(v));
  });
  std::vector<double> y(kW, kBoundary);
  RaiseToSkyEnd(cloud, std::vector<uint8_t>(kW, 0), y);
  EXPECT_GE(CountAt(y, kBoundary), 0.95 * kW);

  // Sky straight down to the boundary.
  const cv::Mat clear = Scene([](int, int row) { return cv::Vec3b(185, 150 + row / 12, 118 + row / 12); });
  y.assign(kW, kBoundary);
  RaiseToSkyEnd(clear, std::vector<uint8_t>(kW, 0), y);
  EXPECT_EQ(CountAt(y, kBoundary), kW);
}

TEST(RaiseToSkyEnd, NullAndSkippedColumnsAreLeftAlone) {
  const cv::Mat img = Scene([](int x, int y) {
    const int n = (x * 37 + y * 91 + x * y * 7) % 21 - 10;
    return cv::Vec3b::all(cv::saturate_cast<uchar>(160 + n));
  });
  std::vector<double> y(kW, kBoundary);
  std::vector<uint8_t> skip(kW, 0);
  for (int x = 0; x < kW; x += 2) skip[x] = 1;
  y[1] = NAN;
  RaiseToSkyEnd(img, skip, y);
  EXPECT_TRUE(std::isnan(y[1]));
  for (int x = 0; x < kW; x += 2) EXPECT_EQ(y[x], kBoundary) << x;
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.45 * kW);  // the other odd columns
}

// RaiseToSkyModelDeparture on a scene: the sky model fitted to the rows
// above kTop - 3 (work planes at full size), the boundary given at
// kBoundary in every column; returns the boundary and the one it moved from.
template <typename Band>
std::pair<std::vector<double>, std::vector<double>> RaiseBySkyModel(Band band, std::vector<uint8_t> skip = {}) {
  const cv::Mat img = Scene(band);
  LabPlanes planes;
  LabConverter::Instance().ConvertTransposed(img, planes);
  SkyModel model;
  model.Fit(planes, std::vector<int>(kW, kTop - 3), 2, 1.0f);
  std::vector<double> y(kW, kBoundary), alt;
  if (skip.empty()) skip.assign(kW, 0);
  y[1] = NAN;
  RaiseToSkyModelDeparture(img, model, 1.0, 1.0, -25.0f, skip, y, alt);
  return {y, alt};
}

TEST(RaiseToSkyModelDeparture, AFarRidgeAboveAClearerEdgeRaisesTheBoundary) {
  // A far snow ridge in haze, smooth and paler than the sky (about 10
  // delta E), over the bright near snow where the boundary was found.
  const auto [y, alt] = RaiseBySkyModel([](int, int) { return cv::Vec3b(205, 190, 175); });
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.95 * (kW - 1));
  for (int x = 0; x < kW; ++x) {
    if (std::isfinite(y[x]) && std::abs(y[x] - (kTop - 0.5)) <= 1.0) {
      EXPECT_EQ(alt[x], kBoundary) << x;
    }
  }
  EXPECT_TRUE(std::isnan(y[1]));
  EXPECT_TRUE(std::isnan(alt[1]));
}

TEST(RaiseToSkyModelDeparture, SkyDownToTheBoundaryOrADeepBlueBandStays) {
  // The sky's own gradient straight down to the boundary.
  auto [y, alt] = RaiseBySkyModel([](int, int row) { return cv::Vec3b(185, 150 + row / 12, 118 + row / 12); });
  EXPECT_EQ(CountAt(y, kBoundary), kW - 1);
  EXPECT_TRUE(std::all_of(alt.begin(), alt.end(), [](double v) { return std::isnan(v); }));
  // A band of saturated blue (b* far below -25) under a paler sky: sky.
  std::tie(y, alt) = RaiseBySkyModel([](int, int) { return cv::Vec3b(230, 120, 40); });
  EXPECT_EQ(CountAt(y, kBoundary), kW - 1);
}

TEST(RaiseToSkyModelDeparture, SkippedColumnsAreLeftAlone) {
  std::vector<uint8_t> skip(kW, 0);
  for (int x = 0; x < kW; x += 2) skip[x] = 1;
  const auto [y, alt] = RaiseBySkyModel([](int, int) { return cv::Vec3b(205, 190, 175); }, skip);
  for (int x = 0; x < kW; x += 2) {
    EXPECT_EQ(y[x], kBoundary) << x;
    EXPECT_TRUE(std::isnan(alt[x])) << x;
  }
  EXPECT_GE(CountAt(y, kTop - 0.5), 0.45 * kW);
}

TEST(RaiseToSkyModelDeparture, ASkyTheModelDoesNotFitAboveTheBandStays) {
  // The model learnt a blue sky, but over this boundary the sky is a
  // sunset's yellow glow (AKJNC_20121001): the glow departs from the model
  // as much as the band does, so the band's departure tells nothing.
  SkyModel model;
  {
    LabPlanes planes;
    LabConverter::Instance().ConvertTransposed(Scene([](int, int) { return cv::Vec3b(205, 190, 175); }), planes);
    model.Fit(planes, std::vector<int>(kW, kTop - 3), 2, 1.0f);
  }
  cv::Mat img = Scene([](int, int) { return cv::Vec3b(205, 190, 175); });
  for (int y = 0; y < kTop; ++y)
    for (int x = 0; x < kW; ++x) img.at<cv::Vec3b>(y, x) = cv::Vec3b(150, 205, 240);
  std::vector<double> y(kW, kBoundary), alt;
  RaiseToSkyModelDeparture(img, model, 1.0, 1.0, -25.0f, std::vector<uint8_t>(kW, 0), y, alt);
  EXPECT_EQ(CountAt(y, kBoundary), kW);
}

TEST(RaiseToSkyModelDeparture, ABandThatTurnsBackToSkyOverContrastyTerrainStays) {
  // A pale band in the sky whose colour returns to the sky's two rows above
  // a boundary that departs four times as much (a glow's ring over a dark
  // ridge): sky lies between the band and the terrain, so the band is no
  // ridge. The same band reaching down to the boundary is one (first test).
  const auto [y, alt] = RaiseBySkyModel([](int, int row) {
    return row < kBoundary - 2 ? cv::Vec3b(205, 190, 175) : cv::Vec3b(185, 150 + row / 12, 118 + row / 12);
  });
  EXPECT_EQ(CountAt(y, kBoundary), kW - 1);
}

// RaiseToFirstDeparture on columns of: sky (CIELAB L* 55, b* -12) down to
// row kCrest, then `band(row)` (L*, b*) down to kBoundary, then `ground`;
// every column's boundary found at kBoundary (the band's lower edge).
constexpr int kCrest = kBoundary - 4;

cv::Vec3b FromLab(float l, float b) {
  cv::Mat lab(1, 1, CV_32FC3, cv::Scalar(l, 0.0f, b)), bgr;
  cv::cvtColor(lab, bgr, cv::COLOR_Lab2BGR);
  cv::Vec3f v = bgr.at<cv::Vec3f>(0, 0);
  return cv::Vec3b(cv::saturate_cast<uchar>(255 * v[0]), cv::saturate_cast<uchar>(255 * v[1]),
                   cv::saturate_cast<uchar>(255 * v[2]));
}

template <typename Band>
std::vector<double> RaiseToFirstDepartureIn(Band band, cv::Vec3b ground, std::vector<uint8_t> skip = {},
                                            cv::Vec3b sky = FromLab(55, -12), bool sky_at_boundary = false) {
  cv::Mat img(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; ++y) {
    const cv::Vec3b c = y < kCrest                          ? sky
                        : y < kBoundary                     ? band(y)
                        : y == kBoundary && sky_at_boundary ? sky
                                                            : ground;
    for (int x = 0; x < kW; ++x) img.at<cv::Vec3b>(y, x) = c;
  }
  std::vector<double> y(kW, kBoundary);
  y[1] = NAN;
  if (skip.empty()) skip.assign(kW, 0);
  RaiseToFirstDeparture(img, skip, y);
  return y;
}

TEST(RaiseToFirstDeparture, ADarkCrestOverBrightSnowRaisesTheBoundaryToItsTop) {
  // A rock crest 4 delta L darker than the sky (the ground's contrast 10).
  const std::vector<double> y = RaiseToFirstDepartureIn([](int) { return FromLab(51, -11); }, FromLab(65, -3));
  EXPECT_TRUE(std::isnan(y[1]));
  for (int x = 0; x < kW; ++x) {
    if (x == 1) continue;
    EXPECT_NEAR(y[x], kCrest, 0.6) << x;
  }
}

TEST(RaiseToFirstDeparture, ADarkCrestWhoseBoundaryRowMatchesTheSkyIsRaised) {
  // The boundary's own row half way from the dark crest to the snow: the
  // sky's lightness.
  const std::vector<double> y =
      RaiseToFirstDepartureIn([](int) { return FromLab(51, -11); }, FromLab(65, -3), {}, FromLab(55, -12), true);
  EXPECT_NEAR(y[100], kCrest, 0.6);
  // Not a bright band over darker ground so (a sky's glow at the horizon).
  const std::vector<double> glow =
      RaiseToFirstDepartureIn([](int) { return FromLab(63, -10); }, FromLab(35, -2), {}, FromLab(55, -12), true);
  EXPECT_EQ(glow[100], kBoundary);
}

TEST(RaiseToFirstDeparture, ABrightRimOverDarkRockRaisesTheBoundary) {
  // A sunlit rim 8 delta L over the sky, then rock 20 under it (the
  // threshold 30% of the larger contrast: 6).
  const std::vector<double> y = RaiseToFirstDepartureIn([](int) { return FromLab(63, -8); }, FromLab(35, -2));
  EXPECT_NEAR(y[100], kCrest, 0.6);
}

TEST(RaiseToFirstDeparture, ASharpEdgeAFaintBandOrABlueBandUnderACloudStays) {
  // Sky straight down to the boundary.
  std::vector<double> y = RaiseToFirstDepartureIn([](int) { return FromLab(55, -12); }, FromLab(70, -2));
  EXPECT_EQ(CountAt(y, kBoundary), kW - 1);
  for (int x = 0; x < kW; ++x) {
    if (x == 1) continue;
    EXPECT_EQ(y[x], kBoundary) << x;
  }
  // A band 1.5 delta L off the sky: below the least departure (JPEG's blocks).
  y = RaiseToFirstDepartureIn([](int) { return FromLab(53.5, -12); }, FromLab(70, -2));
  EXPECT_EQ(y[100], kBoundary);
  // A white cloud the sky's lines are fitted to, over a band of blue sky.
  y = RaiseToFirstDepartureIn([](int) { return FromLab(60, -35); }, FromLab(40, 5), {}, FromLab(90, -5));
  EXPECT_EQ(y[100], kBoundary);
}

TEST(RaiseToFirstDeparture, SkippedColumnsAreLeftAlone) {
  std::vector<uint8_t> skip(kW, 0);
  for (int x = 0; x < kW; x += 2) skip[x] = 1;
  const std::vector<double> y = RaiseToFirstDepartureIn([](int) { return FromLab(51, -11); }, FromLab(65, -3), skip);
  for (int x = 0; x < kW; x += 2) EXPECT_EQ(y[x], kBoundary) << x;
  EXPECT_NEAR(y[101], kCrest, 0.6);
}

// RaiseDips on a scene whose boundary was found on the faint ridge's top
// (kTop - 0.5) but for `dips`, found on the clearer edge below it
// (kBoundary); `raised` columns were raised before (their alt set).
template <typename Band>
std::pair<std::vector<double>, std::vector<double>> RaiseDipsIn(Band band, const std::vector<int>& dips,
                                                                const std::vector<int>& raised = {},
                                                                std::vector<uint8_t> skip = {}) {
  const cv::Mat img = Scene(band);
  std::vector<double> y(kW, kTop - 0.5), alt(kW, NAN);
  for (int x : dips) y[x] = kBoundary;
  for (int x : raised) alt[x] = kBoundary;
  if (skip.empty()) skip.assign(kW, 0);
  RaiseDips(img, skip, y, alt);
  return {y, alt};
}

// A far ridge in haze, about 6 delta E off the sky.
cv::Vec3b FaintRidge(int, int) { return cv::Vec3b(196, 178, 160); }

TEST(RaiseDips, AColumnOnTheInnerEdgeRisesToTheRidgeItsNeighboursFound) {
  const auto [y, alt] = RaiseDipsIn(FaintRidge, {50, 100, 101, 150});
  for (int x : {50, 100, 101, 150}) {
    EXPECT_NEAR(y[x], kTop - 0.5, 1.0) << x;
    EXPECT_EQ(alt[x], kBoundary) << x << ": the matching still reads the clearer edge";
  }
  EXPECT_EQ(CountAt(y, kTop - 0.5), kW);
  EXPECT_EQ(std::count_if(alt.begin(), alt.end(), [](double v) { return std::isfinite(v); }), 4);
}

TEST(RaiseDips, ANotchWithSkyDownToItsBoundaryStays) {
  // Sky straight down to kBoundary in columns 98-103: a notch.
  const auto [y, alt] = RaiseDipsIn(
      [](int x, int row) { return x >= 98 && x <= 103 ? cv::Vec3b(185, 150 + row / 12, 118 + row / 12) : FaintRidge(x, row); },
      {98, 99, 100, 101, 102, 103});
  for (int x = 98; x <= 103; ++x) {
    EXPECT_EQ(y[x], kBoundary) << x;
    EXPECT_TRUE(std::isnan(alt[x])) << x;
  }
}

TEST(RaiseDips, RaisedNeighboursAndSkippedColumnsDoNotMove) {
  // The dip at 100 has only raised columns above it within reach (3
  // columns at this width) on both sides: no neighbour to rise to (a
  // sunset's glow raised on both sides of a notch).
  auto [y, alt] = RaiseDipsIn(FaintRidge, {100}, {97, 98, 99, 101, 102, 103});
  EXPECT_EQ(y[100], kBoundary);
  EXPECT_TRUE(std::isnan(alt[100]));
  // Raised on one side only, the other side's columns not raised: it rises
  // (a dip on the inner edge beside columns the sky model raised,
  // AKJNC_20120813's columns 879-880).
  std::tie(y, alt) = RaiseDipsIn(FaintRidge, {100}, {97, 98, 99});
  EXPECT_NEAR(y[100], kTop - 0.5, 1.0);
  EXPECT_EQ(alt[100], kBoundary);
  std::vector<uint8_t> skip(kW, 0);
  skip[60] = 1;
  std::tie(y, alt) = RaiseDipsIn(FaintRidge, {60, 140}, {}, skip);
  EXPECT_EQ(y[60], kBoundary) << "skipped";
  EXPECT_NEAR(y[140], kTop - 0.5, 1.0);
}

// A ridge clear (6 delta E) in columns 0-49, faint (2 delta E, under the
// clear threshold 2.5) in 50-199, an occluder's column at 120, a jump of
// 10 rows at 150 and no boundary found at 160-169: the faint columns join
// from the clear run up to the occluder, none beyond it.
TEST(ContinueFaintColumns, FaintColumnsContinuingAClearRunAreKept) {
  const int w = 200;
  std::vector<ColumnFit> fits(w);
  Skyline out;
  out.width = w, out.height = 100;
  out.y.assign(w, NAN), out.confidence.assign(w, 0.0);
  for (int x = 0; x < w; ++x) {
    fits[x].y = 40.0 + 0.5 * std::sin(x / 7.0) + (x >= 150 ? 10.0 : 0.0);
    fits[x].contrast = x < 50 ? 6.0f : 2.0f;
    if (x < 50) out.y[x] = fits[x].y, out.confidence[x] = 0.2;  // the clear columns, kept before
  }
  for (int x = 160; x < 170; ++x) fits[x].y = NAN;  // no boundary found
  std::vector<uint8_t> skip(w, 0);
  skip[120] = 1;  // an occluder's column
  Skyline strict = out;
  ContinueFaintColumns(fits, skip, 2.5, 3.0, 100, strict);  // threshold above the faint columns: nothing joins
  EXPECT_EQ(strict.VisibleCount(), 50);
  ContinueFaintColumns(fits, skip, 1.5, 3.0, 100, out);
  for (int x = 50; x < 120; ++x) EXPECT_DOUBLE_EQ(out.y[x], fits[x].y) << x;
  EXPECT_DOUBLE_EQ(out.confidence[60], 0.05);
  EXPECT_TRUE(std::isnan(out.y[120])) << "a skipped column stays null";
  for (int x = 121; x < w; ++x) EXPECT_TRUE(std::isnan(out.y[x])) << x << ": beyond the skipped column or the jump";
  EXPECT_DOUBLE_EQ(out.confidence[10], 0.2) << "a clear column keeps its confidence";
}

// A JPEG's block rows: a run along one grid row long enough is marked; the
// columns off the grid (a level ridge between block rows), a shorter run
// and one broken by a null are not; a boundary stepping from one grid row
// to the next makes two runs, each judged on its own.
TEST(GridRunColumns, MarksOnlyLongRunsAlongOneBlockRow) {
  std::vector<double> y(200, 100.3);                         // off the grid (8 k +- 0.75)
  for (int x = 10; x < 60; ++x) y[x] = 144.0 + 0.5 * ((x % 3) - 1);  // 50 columns on row 144
  for (int x = 70; x < 95; ++x) y[x] = 128.1;                // 25 columns on row 128
  for (int x = 100; x < 160; ++x) y[x] = x < 120 ? 64.2 : 72.2;  // 20 + 40 on two rows
  for (int x = 165; x < 200; ++x) y[x] = 40.0;               // 35 columns ...
  y[180] = NAN;                                              // ... broken by a null
  const std::vector<uint8_t> runs = GridRunColumns(y, 8, 0.75, 30);
  for (int x = 0; x < 200; ++x) {
    const bool expected = (x >= 10 && x < 60) || (x >= 120 && x < 160);
    EXPECT_EQ(runs[x] != 0, expected) << x;
  }
  // The same with a shorter least run takes the 25 columns too.
  EXPECT_EQ(GridRunColumns(y, 8, 0.75, 20)[80], 1);
  EXPECT_TRUE(GridRunColumns({}, 8, 0.75, 10).empty());
}

// Short stretches between long gaps are marked; a long one, a short run
// joined to a long one across a short gap, and one at the image's edge are
// not; runs across short gaps count as one stretch.
TEST(IsolatedRunColumns, MarksShortStretchesBetweenLongGaps) {
  std::vector<double> y(200, NAN);
  for (int x = 0; x < 5; ++x) y[x] = 10.0;      // at the left edge
  for (int x = 20; x < 26; ++x) y[x] = 50.0;    // 6 columns, gaps 15 and 14: isolated
  for (int x = 40; x < 80; ++x) y[x] = 60.0;    // long
  for (int x = 84; x < 88; ++x) y[x] = 70.0;    // gap of 4 on the left: a ridge's broken part
  for (int x = 120; x < 130; ++x) y[x] = 20.0;  // 10 columns, gaps 32 and 50: isolated if 10 may be
  y[150] = y[153] = y[154] = 30.0;              // one stretch of 5 across a gap of 2, then nulls to the edge
  const std::vector<uint8_t> iso = IsolatedRunColumns(y, 8, 10);
  for (int x = 0; x < 200; ++x) {
    const bool expected = (x >= 20 && x < 26) || x == 150 || x == 153 || x == 154;
    EXPECT_EQ(iso[x] != 0, expected) << x;
  }
  EXPECT_EQ(IsolatedRunColumns(y, 10, 10)[125], 1);
  std::vector<double> right(50, NAN);
  for (int x = 45; x < 50; ++x) right[x] = 5.0;  // at the right edge
  EXPECT_EQ(IsolatedRunColumns(right, 8, 10)[47], 0);
  EXPECT_TRUE(IsolatedRunColumns({}, 8, 10).empty());
}

// Column fits along a level ridge at row 150 of a 648-row image, 972
// columns (AKJNC_20120605's size), bright ground.
std::vector<ColumnFit> LevelRidge() {
  std::vector<ColumnFit> fits(972);
  for (ColumnFit& f : fits) f.y = 150.0, f.ground_l = 80.0;
  return fits;
}

TEST(FindOccluders, ASpikeCutByTheImagesEdgeIsAnOccluder) {
  // A pole rising 40 px near the right edge, another near the left.
  std::vector<ColumnFit> fits = LevelRidge();
  for (int x = 900; x < 972; ++x) fits[x].y = 110.0;
  for (int x = 0; x < 60; ++x) fits[x].y = 110.0;
  const std::vector<uint8_t> occ = FindOccluders(fits, 648);
  EXPECT_TRUE(std::all_of(occ.begin() + 902, occ.end(), [](uint8_t o) { return o == 1; }));
  EXPECT_TRUE(std::all_of(occ.begin(), occ.begin() + 58, [](uint8_t o) { return o == 1; }));
  EXPECT_EQ(std::count(occ.begin() + 100, occ.begin() + 850, 1), 0);
}

TEST(FindOccluders, ADipNearTheImagesEdgeIsNone) {
  // The boundary fell 15 px onto an inner edge for 20 columns, then rose 20
  // px back above the ridge's level before it: near the right edge, where
  // its rise once read as a pole cut by the edge (a copy of AKJNC_20120605
  // a third of a stop darker lost its last 100 columns), and mirrored near
  // the left edge.
  std::vector<ColumnFit> fits = LevelRidge();
  for (int x = 861; x < 878; ++x) fits[x].y = 164.0;
  for (int x = 878; x < 972; ++x) fits[x].y = 144.0;
  for (int x = 0; x < 40; ++x) fits[x].y = 144.0;
  for (int x = 40; x < 58; ++x) fits[x].y = 164.0;
  const std::vector<uint8_t> occ = FindOccluders(fits, 648);
  EXPECT_EQ(std::count(occ.begin(), occ.end(), 1), 0);
}

// A sky's smooth gradient over a darker, smoothly shaded ground, 8-bit,
// with Gaussian noise of `sigma` levels per channel (seeded).
cv::Mat GradientWithNoise(double sigma) {
  cv::Mat img(300, 400, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      img.at<cv::Vec3b>(y, x) = y < 150 ? cv::Vec3b(200 - y / 5, 160 - y / 6, 120 - y / 8)
                                        : cv::Vec3b(60 + x / 10, 90 + x / 12, 70 + (y - 150) / 6);
  if (sigma > 0.0) testing::AddPixelNoise(img, sigma, 11);
  return img;
}

// A hazy photo's grey sky (level 150, L* 62) over a ridge's top 4 rows
// darker by 3.7 delta E (140), over snow 7.4 lighter than the ridge (160):
// each column's refinement, centred between the two steps, takes the
// snow's edge as taken (the ridge's step is half the snow's, but under the
// least clear step of 5 delta E) and the ridge's top when the lightness
// difference counts 2.5 times (a photo spanning 40% of the scale).
TEST(RefineColumn, AFaintRidgeTopIsClearOverTheLightnessStretched) {
  constexpr int w = 40, h = 80, ridge = 40, snow = 44;
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    const uint8_t v = y < ridge ? 150 : y < snow ? 140 : 160;
    img.row(y).setTo(cv::Scalar(v, v, v));
  }
  const int centre = 42, window = 3;
  RefineStrips strips;
  strips.count = 2 * window + 10;
  strips.first.assign(w, centre - window - 5);
  GatherStrips(img, strips);
  for (int x = 0; x < w; ++x) {
    EXPECT_NEAR(RefineColumn(strips, x, h, centre, window).y, snow, 0.6) << "column " << x;
    EXPECT_NEAR(RefineColumn(strips, x, h, centre, window, 1.0f).y, snow, 0.6) << "column " << x;
    EXPECT_NEAR(RefineColumn(strips, x, h, centre, window, 2.5f).y, ridge, 0.6) << "column " << x;
  }
}

TEST(NoiseSigma, ReadsThePixelNoiseNotTheScenesGradientsOrEdges) {
  // Noise of sigma s per channel is s * 0.668 in luma (0.114, 0.587, 0.299).
  EXPECT_LT(NoiseSigma(GradientWithNoise(0.0)), 0.5);
  for (double s : {3.0, 6.0, 10.0}) {
    const double got = NoiseSigma(GradientWithNoise(s));
    EXPECT_NEAR(got, 0.668 * s, 0.12 * 0.668 * s) << "sigma " << s;
  }
}

TEST(NoiseSigma, TextureAloneReadsAsLittleNoise) {
  // Blocks of random shade 8 px across (rock and snow): edges on 1 in 4
  // rows and columns, the rest flat.
  cv::Mat img(240, 320, CV_8UC3);
  cv::RNG rng(3);
  cv::Mat cells(30, 40, CV_8U);
  rng.fill(cells, cv::RNG::UNIFORM, 40, 220);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const uint8_t v = cells.at<uint8_t>(y / 8, x / 8);
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(v, v, v);
    }
  EXPECT_LT(NoiseSigma(img), 1.0);
  EXPECT_EQ(NoiseSigma(cv::Mat()), 0.0);
  EXPECT_EQ(NoiseSigma(cv::Mat(2, 2, CV_8UC3, cv::Scalar(1, 2, 3))), 0.0);
}

}  // namespace
}  // namespace horizonreg::skyline_detail
