// SPDX-License-Identifier: MIT
#include "skyline/skyline.h"

#include <gtest/gtest.h>

#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "testing/pixel_noise.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

// Blue sky over green terrain with a sloped, bumpy skyline at known rows.
cv::Mat SyntheticScene(int w, int h, std::vector<double>& truth) {
  cv::Mat img(h, w, CV_8UC3);
  truth.resize(w);
  for (int x = 0; x < w; ++x) truth[x] = 0.45 * h + 0.05 * x + 20.0 * std::sin(x / 37.0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool sky = y + 0.5 < truth[x];
      img.at<cv::Vec3b>(y, x) =
          sky ? cv::Vec3b(235, 200 - 50 * y / h, 160 - 50 * y / h) : cv::Vec3b(60, 120 + (x * 7 + y * 13) % 20, 70);
    }
  return img;
}

// Gaussian pixel noise of `sigma` levels per channel (seeded: the same
// noise every run).
void AddNoise(cv::Mat& img, double sigma) { testing::AddPixelNoise(img, sigma); }

// Columns in [x0, x1) (all when x1 < 0) whose boundary lies within `px` of
// the scene's true row.
int WithinPx(const Skyline& s, const std::vector<double>& truth, double px, int x0 = 0, int x1 = -1) {
  int good = 0;
  for (int x = x0; x < (x1 < 0 ? s.width : x1); ++x)
    if (std::isfinite(s.y[x]) && std::abs(s.y[x] - std::ceil(truth[x] - 0.5)) <= px) ++good;
  return good;
}
// Columns in [x0, x1) given a row.
int GivenIn(const Skyline& s, int x0, int x1) {
  int given = 0;
  for (int x = x0; x < x1; ++x) given += std::isfinite(s.y[x]) ? 1 : 0;
  return given;
}
int WithinAPixel(const Skyline& s, const std::vector<double>& truth) { return WithinPx(s, truth, 1.0); }

// A thin strip of uniform sky over a blocky random texture subtracted from
// a bright ground colour (snow and shadowed rock, or sunlit and shaded
// snow): `truth` is the strip's bottom row per column, `block` the
// texture's cell size in pixels, `depth` its largest darkening (seeded:
// the same scene every run).
cv::Mat ThinSkyOverTexture(int w, int h, const std::vector<double>& truth, uint64_t seed, int block, int depth,
                           const cv::Vec3b& sky, const cv::Vec3b& ground) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(seed);
  cv::Mat texture((h + block - 1) / block, (w + block - 1) / block, CV_8U);
  rng.fill(texture, cv::RNG::UNIFORM, 0, depth);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int t = texture.at<uint8_t>(y / block, x / block);
      img.at<cv::Vec3b>(y, x) = y + 0.5 < truth[x] ? sky : cv::Vec3b(ground[0] - t, ground[1] - t, ground[2] - t);
    }
  return img;
}

TEST(SkylineOptions, DefaultsAreValid) { EXPECT_NO_THROW(SkylineOptions{}.Check()); }

TEST(ExtractSkyline, FindsASyntheticSkylineWithinAPixel) {
  std::vector<double> truth;
  const cv::Mat img = SyntheticScene(640, 400, truth);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  ASSERT_EQ(s.width, 640);
  EXPECT_GE(WithinAPixel(s, truth), 620);
}

// A webcam's timestamp strip (black, white text) along the top edge, and
// one along the bottom: the skyline between them, in the photo's rows, as
// without them. A flat sky reaching the top edge (no text) is no strip.
TEST(ExtractSkyline, TimestampStripsAreNotScene) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(640, 400, truth);
  // A pale hazy sky over dark grey rock (a black strip over it reads as a
  // night sky above pale terrain).
  for (int y = 0; y < 400; ++y)
    for (int x = 0; x < 640; ++x)
      img.at<cv::Vec3b>(y, x) = y + 0.5 < truth[x] ? cv::Vec3b(205, 195, 190 - 10 * y / 400)
                                                   : cv::Vec3b(90 + (x * 7 + y * 13) % 20, 95, 100);
  AddNoise(img, 1.0);
  cv::rectangle(img, {0, 0}, {639, 21}, cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(img, "2026-11-28 15:04:10  CAM 3", {6, 16}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1);
  cv::rectangle(img, {0, 380}, {639, 399}, cv::Scalar(40, 40, 40), cv::FILLED);
  cv::putText(img, "T 12.4 C", {6, 395}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  ASSERT_EQ(s.height, 400);
  EXPECT_GE(WithinAPixel(s, truth), 620);
  // A flat sky reaching the top edge, no text: read as before.
  cv::Mat plain = SyntheticScene(640, 400, truth);
  cv::rectangle(plain, {0, 0}, {639, 21}, cv::Scalar(235, 200, 160), cv::FILLED);
  EXPECT_GE(WithinAPixel(ExtractSkyline(plain, SkylineOptions{}), truth), 620);
}

// Large and odd sizes take the whole-factor reduction (which drops the last
// rows and columns) and then the resize to the work width; every column,
// the last ones too, must map back to the right full-size rows. The same
// image twice checks that the per-thread scratch images carry nothing over.
TEST(ExtractSkyline, LargeOddSizedImagesMapBackToFullSizeRows) {
  for (const auto& [w, h] : {std::pair{3001, 2003}, std::pair{1025, 683}, std::pair{1500, 601}}) {
    std::vector<double> truth;
    cv::Mat img = SyntheticScene(w, h, truth);
    for (int pass = 0; pass < 2; ++pass) {
      const Skyline s = ExtractSkyline(img, SkylineOptions{});
      ASSERT_EQ(s.width, w);
      EXPECT_GE(WithinAPixel(s, truth), 0.97 * w) << w << " x " << h << " pass " << pass;
      for (int x = w - 3; x < w; ++x) EXPECT_NEAR(s.y[x], std::ceil(truth[x] - 0.5), 1.0) << w << " x " << h;
    }
  }
}

TEST(ExtractSkyline, WideImagesAreReadAtAbout1024Columns) {
  EXPECT_EQ(ExtractionReduction(1024, 683), 1);
  EXPECT_EQ(ExtractionReduction(1535, 1000), 1);
  EXPECT_EQ(ExtractionReduction(1536, 1000), 2);
  EXPECT_EQ(ExtractionReduction(3001, 2003), 3);
  EXPECT_EQ(ExtractionReduction(4000, 3000), 4);
  EXPECT_EQ(ExtractionReduction(6000, 4000), 6);
  EXPECT_EQ(ExtractionReduction(4000, 20), 2);  // a thin strip keeps 8 rows
  EXPECT_THROW(BlockMeans(cv::Mat(10, 10, CV_8UC3), 1), InvalidArgument);
  EXPECT_THROW(BlockMeans(cv::Mat(10, 10, CV_8UC1), 2), InvalidArgument);
  const cv::Mat m = BlockMeans(cv::Mat(10, 11, CV_8UC3, cv::Scalar(10, 20, 30)), 3);
  EXPECT_EQ(m.cols, 3);
  EXPECT_EQ(m.rows, 3);
  EXPECT_EQ(m.at<cv::Vec3b>(2, 2), cv::Vec3b(10, 20, 30));
}

// A photo with 4x the pixels (a phone's 4000 columns against an archive's
// 1000) spreads a hazy ridge's soft edge over 4x the rows: read at full
// size, steps between neighbouring rows and colours 2-4 rows from the edge
// fade. Read at its reduced size and placed at full size, it gives the
// skyline of the smaller photo, scaled.
TEST(ExtractSkyline, AnUpscaledPhotoGivesTheSameSkylineScaled) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(1000, 660, truth);
  for (int y = 0; y < img.rows; ++y)  // a hazy far ridge: a few delta E off the sky
    for (int x = 0; x < img.cols; ++x)
      if (y + 0.5 >= truth[x]) img.at<cv::Vec3b>(y, x) = cv::Vec3b(212, 178, 150);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 1.5);
  AddNoise(img, 2.0);  // and the camera's noise
  cv::Mat big;
  cv::resize(img, big, cv::Size(), 4.0, 4.0, cv::INTER_CUBIC);
  const Skyline small = ExtractSkyline(img, SkylineOptions{}), large = ExtractSkyline(big, SkylineOptions{});
  ASSERT_EQ(large.width, 4000);
  int small_good = 0, large_good = 0;
  for (int x = 0; x < 1000; ++x) {
    const double t = std::ceil(truth[x] - 0.5);
    small_good += std::isfinite(small.y[x]) && std::abs(small.y[x] - t) <= 2.0;
    for (int k = 0; k < 4; ++k) {
      const double v = large.y[4 * x + k];
      large_good += std::isfinite(v) && std::abs(v - 4.0 * t) <= 8.0;
    }
  }
  EXPECT_GE(small_good, 950);
  EXPECT_GE(large_good, 0.97 * 4 * small_good);  // read at full size: 3629 of 4000 (measured)
}

// A photo 3 stops underexposed (8-bit values times 0.125^(1/2.2)) of a hazy
// far ridge a few delta E off the sky: every step shrinks by half, and the
// extraction's thresholds are in delta E. Brightened back before the
// extraction, it gives the skyline of the photo exposed right.
TEST(ExtractSkyline, AnUnderexposedPhotoReadsAsExposedRight) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(1000, 660, truth);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (y + 0.5 >= truth[x]) img.at<cv::Vec3b>(y, x) = cv::Vec3b(212, 178, 150);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 1.5);
  AddNoise(img, 2.0);
  cv::Mat dark;
  img.convertTo(dark, -1, std::pow(0.125, 1.0 / 2.2));
  const Skyline exposed = ExtractSkyline(img, SkylineOptions{}), under = ExtractSkyline(dark, SkylineOptions{});
  int good = 0, same = 0;
  for (int x = 0; x < img.cols; ++x) {
    good += std::isfinite(exposed.y[x]) && std::abs(exposed.y[x] - std::ceil(truth[x] - 0.5)) <= 2.0;
    same += std::isfinite(exposed.y[x]) && std::isfinite(under.y[x]) && std::abs(under.y[x] - exposed.y[x]) <= 0.25;
  }
  EXPECT_GE(good, 950);
  // Measured 80% within a quarter pixel (the dark copy's 8-bit steps are
  // 2.6 times coarser); 40% without the brightening.
  EXPECT_GE(same, 0.75 * img.cols);
}

// Pixel noise of a high-ISO photo (sigma 8 levels per channel) must not pass
// for the topmost clear step in the sky above a faint (hazy) ridge.
TEST(ExtractSkyline, NoisySkyAboveAHazyRidgeIsNotTakenForTheSkyline) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(1024, 683, truth);
  for (int y = 0; y < img.rows; ++y)  // a hazy far ridge: terrain only a little darker and greyer than the sky
    for (int x = 0; x < img.cols; ++x)
      if (y + 0.5 >= truth[x]) img.at<cv::Vec3b>(y, x) = cv::Vec3b(205, 180, 160);
  AddNoise(img, 8.0);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  int good = 0, given = 0;
  for (int x = 0; x < 1024; ++x) {
    given += std::isfinite(s.y[x]);
    if (std::isfinite(s.y[x]) && std::abs(s.y[x] - std::ceil(truth[x] - 0.5)) <= 2.0) ++good;
  }
  EXPECT_GE(given, 0.9 * 1024);
  // Measured 99% within 2 px, smoothed first (skyline_detail::NoiseSigma
  // about 5.3); 76% read from the noisy pixels.
  EXPECT_GE(good, 0.95 * 1024);
}

TEST(ExtractSkyline, SensorNoiseOverAFaintRidgeIsSmoothedAwayFirst) {
  // A far ridge a few delta E off the sky under the noise of a high ISO or a
  // small webcam sensor (sigma 6 per channel): its boundary is read after
  // an edge-keeping smoothing (skyline_detail::NoiseSigma over 3).
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(1024, 683, truth);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (y + 0.5 >= truth[x]) img.at<cv::Vec3b>(y, x) = cv::Vec3b(215, 178, 150);
  AddNoise(img, 6.0);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  int given = 0;
  for (int x = 0; x < 1024; ++x) given += std::isfinite(s.y[x]);
  // Measured 1018 of 1024 columns within 2 px (1003 within 1); read from
  // the noisy pixels, 786 of 955 given.
  EXPECT_GE(given, 0.98 * 1024);
  EXPECT_GE(WithinPx(s, truth, 2.0), 0.95 * 1024);
}

// A thin strip of smooth sky over textured snow (a camera pitched down, as
// at many time-lapse stations): the sky's noise is the strip's, not the
// snow's texture below it, and the boundary keeps its columns.
TEST(ExtractSkyline, ThinSkyStripOverTexturedSnowKeepsItsColumns) {
  const int w = 768, h = 512;
  std::vector<double> truth(w);
  for (int x = 0; x < w; ++x) truth[x] = 22.0 + 6.0 * std::sin(x / 41.0);
  // Sunlit snow and shadowed rock in 4 px blocks.
  const cv::Mat img = ThinSkyOverTexture(w, h, truth, 11, 4, 90, cv::Vec3b(215, 185, 160), cv::Vec3b(250, 248, 245));
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  const int given = s.VisibleCount(), good = WithinPx(s, truth, 2.0);
  EXPECT_GE(given, 0.9 * w);
  EXPECT_GE(good, 0.85 * w);
}

// A thin strip of pale sky over bright, textured snow down to the bottom
// of the frame (no dark foreground; about 8 delta E between them): the
// first pass takes the snow for sky, so the rows it leaves above its
// boundary are mostly snow. The sky's noise is still the strip's own (read
// above each column's first clear step), and the boundary keeps its
// columns. Measured: none of the 768 columns given while the sky's noise
// was read down to the first pass's boundary; 734 given, 697 within 2 px,
// by the first clear steps.
TEST(ExtractSkyline, ThinPaleSkyOverSnowToTheBottomKeepsItsColumns) {
  const int w = 768, h = 512;
  std::vector<double> truth(w);
  for (int x = 0; x < w; ++x) truth[x] = 18.0 + 5.0 * std::sin(x / 37.0);
  // Sunlit and shaded snow in 2 px blocks.
  const cv::Mat img = ThinSkyOverTexture(w, h, truth, 5, 2, 41, cv::Vec3b(232, 222, 214), cv::Vec3b(242, 240, 238));
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  const int given = s.VisibleCount(), good = WithinPx(s, truth, 2.0);
  std::printf("[ skyline ] thin pale sky over snow: %d given, %d within 2 px of %d\n", given, good, w);
  EXPECT_GE(given, 0.85 * w);
  EXPECT_GE(good, 0.8 * w);
}

// Rock reaching the top of the frame over a third of the width, with small
// snow patches near its top (a steep near mountain, or one cut by a
// timestamp strip): the patches' top rows look like the pale sky, and each
// patch alone gave a few columns of "skyline" there. Those columns are
// null; the skyline either side is read as before.
TEST(ExtractSkyline, SnowPatchesInRockReachingTheTopAreNoSkyline) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(640, 400, truth);
  for (int x = 0; x < 640; ++x) {
    if (x >= 200 && x < 420) truth[x] = 0.0;  // rock up to the top edge
    for (int y = 0; y < 400; ++y)
      img.at<cv::Vec3b>(y, x) = y + 0.5 < truth[x] ? cv::Vec3b(205, 195, 190 - 10 * y / 400)
                                                   : cv::Vec3b(112, 98, 92);
  }
  for (int p = 0; p < 5; ++p)  // 4 x 5 px patches of snow, 40 columns apart
    cv::rectangle(img, {220 + 40 * p, 6 + 3 * (p % 2)}, {223 + 40 * p, 10 + 3 * (p % 2)}, cv::Scalar(228, 226, 224),
                  cv::FILLED);
  AddNoise(img, 1.0);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_EQ(GivenIn(s, 215, 405), 0);
  EXPECT_GE(WithinPx(s, truth, 1.0, 0, 190) + WithinPx(s, truth, 1.0, 430, 640), 0.95 * 400);
}

// A camera held askew under a thin strip of overcast sky (a copy of
// AK10_20090803 turned by 6 deg): a shaded slope leaves the frame through
// its top left corner, and under it lies a bright glacier. The top edge is
// that slope's boundary with the sky above the frame, not the slope's foot
// on the glacier, which pass 1 and the DP took for the skyline (its step
// earned a reward, the frame's edge none), and the histograms then learnt
// the slope as sky. Rock textured as rock is, a sky as smooth as a sky.
TEST(ExtractSkyline, ASlopeLeavingTheFrameThroughTheTopIsNoSkyline) {
  const int w = 640, h = 400;
  std::vector<double> ridge(w), foot(w);
  for (int x = 0; x < w; ++x) {
    ridge[x] = -40.0 + 0.25 * x + 4.0 * std::sin(x / 23.0);  // above the frame left of x ~ 160
    foot[x] = std::max(45.0, ridge[x] + 40.0);            // the slope's foot on the glacier
  }
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(7);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int t = rng.uniform(-9, 10);
      if (y + 0.5 < ridge[x])
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(178, 172, 168);  // overcast, L* ~ 70
      else if (y + 0.5 < foot[x])
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(110 + t, 84 + t, 72 + t);  // shaded slope, bluish, L* ~ 36
      else
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(196 + t, 190 + t, 184 + t);  // glacier ice, L* ~ 76
    }
  AddNoise(img, 1.0);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_LE(GivenIn(s, 0, 150), 10);
  EXPECT_GE(WithinPx(s, ridge, 1.0, 200, w), 0.95 * (w - 200));
}

TEST(ExtractSkyline, UniformAllSkyAndAllGroundImagesGiveAllNull) {
  const cv::Mat grey(300, 400, CV_8UC3, cv::Scalar(128, 128, 128));
  const cv::Mat sky(300, 400, CV_8UC3, cv::Scalar(235, 200, 160));
  const cv::Mat ground(300, 400, CV_8UC3, cv::Scalar(60, 130, 70));
  for (const cv::Mat* m : {&grey, &sky, &ground}) {
    const Skyline s = ExtractSkyline(*m, SkylineOptions{});
    EXPECT_EQ(s.VisibleCount(), 0);
  }
}

TEST(ExtractSkyline, RejectsEmptyImagesAndBadOptions) {
  EXPECT_THROW(ExtractSkyline(cv::Mat(), SkylineOptions{}), InvalidArgument);
  SkylineOptions o;
  o.roll_hint_deg = 80.0;
  EXPECT_THROW(o.Check(), InvalidArgument);
}

TEST(ExtractSkyline, DarkTreeInFrontOfTheHorizonIsNull) {
  std::vector<double> truth;
  cv::Mat img = SyntheticScene(640, 400, truth);
  // A dark green cone rising from the ground above the skyline.
  std::vector<cv::Point> tree = {{300, 390}, {340, 390}, {320, 60}};
  cv::fillConvexPoly(img, tree, cv::Scalar(30, 60, 25));
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  for (int x = 316; x <= 324; ++x) EXPECT_FALSE(std::isfinite(s.y[x])) << x;
  EXPECT_TRUE(std::isfinite(s.y[100]));
}

// Two power cables sagging across the whole sky (dark grey, 2 px,
// anti-aliased) of a photo whose sky pales from deep blue to white at the
// horizon over snowy terrain: the topmost clear edge took the higher one
// for the skyline, and the paler sky below it for terrain. They are erased
// before the boundary is sought.
TEST(ExtractSkyline, CablesAcrossTheSkyAreNotTheSkyline) {
  const int w = 960, h = 600;
  std::vector<double> truth(w);
  cv::Mat img(h, w, CV_8UC3);
  for (int x = 0; x < w; ++x) {
    truth[x] = 300.0 + 0.05 * x + 20.0 * std::sin(x / 37.0) + 6.0 * std::sin(x / 9.0);
    for (int y = 0; y < h; ++y) {
      const double t = std::min(1.0, y / truth[x]);  // 0 at the top, 1 at the horizon
      img.at<cv::Vec3b>(y, x) =
          y + 0.5 < truth[x]
              ? cv::Vec3b(static_cast<uint8_t>(200 + 40 * t), static_cast<uint8_t>(120 + 110 * t),
                          static_cast<uint8_t>(60 + 165 * t))
              : cv::Vec3b(static_cast<uint8_t>(205 + (x * 7 + y * 13) % 30), static_cast<uint8_t>(200 + (x * 5 + y * 11) % 30),
                          static_cast<uint8_t>(195 + (x * 3 + y * 17) % 30));
    }
  }
  std::vector<cv::Point> upper, lower;
  for (int x = 0; x < w; ++x) {
    const double t = (x - w / 2.0) / (w / 2.0);
    upper.emplace_back(x, static_cast<int>(std::lround(90.0 + 40.0 * (1.0 - t * t))));
    lower.emplace_back(x, static_cast<int>(std::lround(170.0 + 40.0 * (1.0 - t * t))));
  }
  cv::polylines(img, std::vector<std::vector<cv::Point>>{upper, lower}, false, cv::Scalar(40, 40, 40), 2, cv::LINE_AA);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, truth, 2.0), w * 90 / 100);
}

// A 960 x 600 scene: `sky` down to a bumpy skyline (`truth`), a crest
// `crest_rows` thick under it, then `snow` down to row `snow_end` and
// `below` from there.
cv::Mat SkyOverCrestOverSnow(const cv::Vec3b& sky, const cv::Vec3b& crest, double crest_rows, const cv::Vec3b& snow,
                             int snow_end, const cv::Vec3b& below, std::vector<double>& truth) {
  const int w = 960, h = 600;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(sky[0], sky[1], sky[2]));
  truth.resize(w);
  for (int x = 0; x < w; ++x) {
    truth[x] = 200.0 + 0.05 * x + 20.0 * std::sin(x / 37.0);
    for (int y = static_cast<int>(std::ceil(truth[x] - 0.5)); y < h; ++y)
      img.at<cv::Vec3b>(y, x) = y < truth[x] + crest_rows ? crest : y < snow_end ? snow : below;
  }
  return img;
}

// A dark rock crest, 6 px thick, between a white sky and white snow of
// the sky's colour (an overcast winter day): a thin line between two equal
// colours, as a cable is, but the skyline.
TEST(ExtractSkyline, AThinDarkCrestBetweenWhiteSkyAndSnowIsTheSkyline) {
  const int w = 960;
  std::vector<double> truth;
  const cv::Vec3b snow(232, 233, 233);
  const cv::Mat img =
      SkyOverCrestOverSnow(cv::Vec3b(236, 236, 234), cv::Vec3b(60, 62, 66), 6.0, snow, 600, snow, truth);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, truth, 2.0), w * 90 / 100);
}

// A hazy photo whose lightness spans a third of the scale: a grey sky
// (level 150) over a far snow ridge whose top 4 rows are a haze-faded
// crest 3.7 delta E darker (140), its snow 7.4 lighter (160), dark rock far
// below, and pixel noise of 2 levels. The skyline is the crest's top, not
// the snow's edge 4 rows down (660 of the 960 columns within 2 px before
// the refinement read the lightness stretched over the photo's span).
TEST(ExtractSkyline, AFaintCrestOverSnowInAHazyPhotoIsTheSkyline) {
  const int w = 960;
  std::vector<double> truth;
  cv::Mat img = SkyOverCrestOverSnow(cv::Vec3b(150, 150, 150), cv::Vec3b(140, 140, 140), 4.0, cv::Vec3b(160, 160, 160),
                                     420, cv::Vec3b(95, 95, 95), truth);
  AddNoise(img, 2.0);
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, truth, 2.0), w * 80 / 100) << WithinPx(s, truth, 2.0);
  // The matching still reads the rows as taken: the snow's edge, where the
  // reading over the photo's lightness span moved them up to the crest.
  int snow_edge = 0;
  for (int x = 0; x < w; ++x)
    snow_edge += std::isfinite(s.Alt(x)) && std::abs(s.MatchY(x) - (std::ceil(truth[x] - 0.5) + 4.0)) <= 1.5;
  EXPECT_GE(snow_edge, w / 10);
}

// A blue sky (deep at the top, paler towards the horizon) over snowy,
// textured terrain, with `contrails` soft white bands across it (centre row
// at the left and right edges, Gaussian sigma in px, peak opacity).
struct Contrail {
  double left_row, right_row, sigma, opacity;
};
cv::Mat SkyWithContrails(int w, int h, std::vector<double>& truth, const std::vector<Contrail>& contrails) {
  cv::Mat img(h, w, CV_8UC3);
  truth.assign(w, 0.0);
  for (int x = 0; x < w; ++x) {
    truth[x] = 330.0 + 0.04 * x + 18.0 * std::sin(x / 41.0) + 5.0 * std::sin(x / 11.0);
    for (int y = 0; y < h; ++y) {
      const double t = std::min(1.0, y / truth[x]);
      cv::Vec3d c = y + 0.5 < truth[x] ? cv::Vec3d(190 + 30 * t, 120 + 70 * t, 60 + 90 * t)
                                       : cv::Vec3d(200 + (x * 7 + y * 13) % 40, 195 + (x * 5 + y * 11) % 40,
                                                   190 + (x * 3 + y * 17) % 40);
      if (y + 0.5 < truth[x] - 3.0)
        for (const Contrail& k : contrails) {
          const double row = k.left_row + (k.right_row - k.left_row) * x / (w - 1.0);
          const double a = k.opacity * std::exp(-0.5 * std::pow((y - row) / k.sigma, 2));
          c = c * (1.0 - a) + cv::Vec3d(250, 250, 248) * a;
        }
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(c[0]), cv::saturate_cast<uint8_t>(c[1]),
                                          cv::saturate_cast<uint8_t>(c[2]));
    }
  }
  return img;
}

// Two aircraft contrails across the sky, a fresh one (sigma 2.5 px) and an
// older, spread one (sigma 9 px), wider than a cable: the first clear edge
// from the top took the fresh one's lower edge for the skyline. They are
// erased as bands that leave the sky's colour and come back to it.
TEST(ExtractSkyline, ContrailsAcrossTheSkyAreNotTheSkyline) {
  std::vector<double> truth;
  const cv::Mat img = SkyWithContrails(960, 600, truth, {{230.0, 90.0, 2.5, 0.75}, {70.0, 150.0, 9.0, 0.35}});
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, truth, 2.0), 960 * 90 / 100);
}

// A far ridge in haze, a straight band 14 px high, darker and bluer than a
// pale sky and standing over snow of that sky's colour: a band that leaves
// the sky's colour and comes back to it, as a contrail does, but darker:
// the skyline.
TEST(ExtractSkyline, AHazyFarRidgeOverSnowOfTheSkysColourIsTheSkyline) {
  const int w = 960, h = 600;
  cv::Mat img(h, w, CV_8UC3);
  std::vector<double> truth(w);
  for (int x = 0; x < w; ++x) {
    truth[x] = 260.0 - 0.03 * x;
    for (int y = 0; y < h; ++y) {
      const cv::Vec3b sky(228, 222, 216), ridge(200, 180, 165);
      const cv::Vec3b snow(static_cast<uint8_t>(226 + (x * 7 + y * 13) % 5), static_cast<uint8_t>(221 + (x * 5 + y * 11) % 4),
                           static_cast<uint8_t>(215 + (x * 3 + y * 17) % 4));
      img.at<cv::Vec3b>(y, x) = y + 0.5 < truth[x] ? sky : y + 0.5 < truth[x] + 14.0 ? ridge : snow;
    }
  }
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, truth, 2.0), w * 90 / 100);
}

// Flat sky rows above band_top, a flat band down to ground_top, and
// ground whose green channel carries a fine texture (12 levels).
cv::Mat SkyOverBandOverGround(int w, int h, int band_top, int ground_top, const cv::Vec3b& sky, const cv::Vec3b& band,
                              const cv::Vec3b& ground) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = y < band_top     ? sky
                                : y < ground_top ? band
                                                 : cv::Vec3b(ground[0], ground[1] + (x * 7 + y * 13) % 12, ground[2]);
  return img;
}

// Columns whose boundary lies within a pixel of `row`.
int AtRow(const Skyline& s, double row) {
  int good = 0;
  for (int x = 0; x < s.width; ++x) good += std::isfinite(s.y[x]) && std::abs(s.y[x] - row) <= 1.0;
  return good;
}

// Pale sky over a band of saturated blue sky (as near the horizon, or
// below a cloud base) over terrain: the band is sky, the skyline is under it.
TEST(ExtractSkyline, SaturatedBlueBandAboveTheTerrainIsSky) {
  const int w = 512, h = 300, ground_top = 148;
  const cv::Mat img = SkyOverBandOverGround(w, h, 140, ground_top, cv::Vec3b(250, 234, 221), cv::Vec3b(220, 160, 120),
                                            cv::Vec3b(100, 125, 105));
  EXPECT_GE(AtRow(ExtractSkyline(img, SkylineOptions{}), ground_top), w * 95 / 100);
}

// A clipped sky, white at the top and bluish toward the horizon (L* 96,
// b* -6 to L* 85, b* -20), over a shaded mountain as saturated a blue as a
// deep sky but far darker (L* 38, b* -30), over a bright glacier: measured
// on AK10_20090827 1.3 stops over. The mountain is terrain: the skyline is
// its top, not its foot (where it was taken while any saturated blue was
// sky).
TEST(ExtractSkyline, DarkSaturatedBlueUnderAWhiteSkyIsTerrain) {
  const int w = 512, h = 300, foot = 190;
  std::vector<double> top(w);
  for (int x = 0; x < w; ++x) top[x] = 110.0 + 25.0 * std::sin(x / 45.0);
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int t = (x * 7 + y * 13) % 12;
      const double f = std::min(1.0, y / top[x]);  // 0 at the top, 1 at the mountain
      img.at<cv::Vec3b>(y, x) =
          y + 0.5 < top[x]
              ? cv::Vec3b(255 - static_cast<int>(4 * f), 248 - static_cast<int>(33 * f), 229 - static_cast<int>(38 * f))
          : y < foot ? cv::Vec3b(140 - t, 88 - t, 65 - t)
                     : cv::Vec3b(250 - 2 * t, 245 - 2 * t, 235 - 2 * t);
    }
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  EXPECT_GE(WithinPx(s, top, 1.0), w * 95 / 100);
}

// A deep blue sky below a white cloud, at 0.63 of the cloud's lightness
// (L* 61 under 96; the rendered fuji_02's sits at 0.68), is sky: the
// skyline stays at the terrain below.
TEST(ExtractSkyline, DeepBlueSkyUnderACloudIsStillSky) {
  const int w = 512, h = 300, ground_top = 170;
  const cv::Mat img = SkyOverBandOverGround(w, h, 90, ground_top, cv::Vec3b(245, 245, 245), cv::Vec3b(215, 150, 95),
                                            cv::Vec3b(70, 95, 75));
  EXPECT_GE(AtRow(ExtractSkyline(img, SkylineOptions{}), ground_top), w * 95 / 100);
}

// A faint hazy far ridge above a contrasty near slope: the first clear edge
// from the top is the skyline (the paper's scan), not the strongest one.
TEST(ExtractSkyline, FaintFarRidgeAboveANearSlopeIsTheSkyline) {
  const int w = 512, h = 300;
  cv::Mat img(h, w, CV_8UC3);
  std::vector<double> far(w), near(w);
  for (int x = 0; x < w; ++x) far[x] = 120 + 6 * std::sin(x / 23.0), near[x] = far[x] + 6 + 0.02 * x;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = y < far[x]    ? cv::Vec3b(240, 222, 205)  // pale sky
                                : y < near[x] ? cv::Vec3b(200, 195, 185)  // hazy far ridge
                                              : cv::Vec3b(70, 125, 90);   // near green slope
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  int good = 0;
  for (int x = 0; x < w; ++x) good += std::isfinite(s.y[x]) && std::abs(s.y[x] - std::ceil(far[x])) <= 1.5;
  EXPECT_GE(good, w * 90 / 100);
}

// Fog: terrain fades into the fog colour over many rows and no horizon is
// seen; the fade is not a skyline.
TEST(ExtractSkyline, TerrainFadingIntoFogGivesAllNull) {
  const int w = 512, h = 300;
  cv::Mat img(h, w, CV_8UC3);
  const cv::Vec3f fog(238, 232, 228), ground(110, 150, 125);
  for (int y = 0; y < h; ++y) {
    const float t = std::clamp((y - 150.0f) / 60.0f, 0.0f, 1.0f);  // 0 fog .. 1 terrain
    for (int x = 0; x < w; ++x) {
      const cv::Vec3f c = (1 - t) * fog + t * ground;
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(c[0], c[1], c[2]);
    }
  }
  EXPECT_EQ(ExtractSkyline(img, SkylineOptions{}).VisibleCount(), 0);
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(ExtractSkyline(grey, SkylineOptions{}).VisibleCount(), 0) << "a grey fade is fog too";
  SkylineOptions o;
  o.fog_contrast = -1;
  EXPECT_THROW(o.Check(), InvalidArgument);
}

// A ridge under a dusk (or underexposed) grey sky: every delta E shrinks
// with the light, so the clearest tenth of the boundary differs by less
// than fog_contrast, though relative to the sky's lightness the edge is as
// clear as by day. Not fog (a copy of a real photo 1.7 stops darker was
// nulled whole); the same edge faded over many rows stays fog.
TEST(ExtractSkyline, RidgeUnderADarkSkyIsNotFog) {
  const int w = 640, h = 400;
  cv::RNG rng(11);
  std::vector<double> ridge(w);
  for (int x = 0; x < w; ++x) ridge[x] = 170.0 + 35.0 * std::sin(x / 80.0) + 8.0 * std::sin(x / 19.0);
  const cv::Vec3d sky(72, 66, 62), ground(40, 41, 38);  // BGR: sky L* about 28, ground about 16
  auto scene = [&](double rows) {
    cv::Mat img(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double t = std::clamp((y + 0.5 - ridge[x]) / rows + 0.5, 0.0, 1.0);  // 0 sky .. 1 ridge
        const cv::Vec3d c = (1 - t) * sky + t * ground;
        const double n = rng.gaussian(0.8);
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(c[0] + n), cv::saturate_cast<uint8_t>(c[1] + n),
                                            cv::saturate_cast<uint8_t>(c[2] + n));
      }
    return img;
  };
  const Skyline s = ExtractSkyline(scene(3.5), SkylineOptions{});
  int good = 0;
  for (int x = 0; x < w; ++x) good += std::isfinite(s.y[x]) && std::abs(s.y[x] - ridge[x]) <= 1.5;
  EXPECT_GE(good, w * 80 / 100);
  EXPECT_EQ(ExtractSkyline(scene(60.0), SkylineOptions{}).VisibleCount(), 0) << "a fade under the same sky is fog";
}

// A grey camera's hazy ridge: a faint (about 7 delta E) edge softened over 3
// rows, with pixel noise. Without chroma it is not taken for fog (as a grey
// copy of a hazy real photo was: every column nulled), while the 60-row
// fade above stays null.
TEST(ExtractSkyline, FaintSoftRidgeInGreyIsNotFog) {
  const int w = 640, h = 400;
  cv::Mat img(h, w, CV_8UC1);
  cv::RNG rng(7);
  std::vector<double> ridge(w);
  for (int x = 0; x < w; ++x) ridge[x] = 160.0 + 30.0 * std::sin(x / 90.0) + 10.0 * std::sin(x / 23.0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double t = std::clamp((y + 0.5 - ridge[x]) / 3.0 + 0.5, 0.0, 1.0);  // 0 sky .. 1 ridge, over 3 rows
      const double v = (1 - t) * 118.0 + t * 100.0 + rng.gaussian(1.5);
      img.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(v);
    }
  const Skyline s = ExtractSkyline(img, SkylineOptions{});
  int good = 0;
  for (int x = 0; x < w; ++x) good += std::isfinite(s.y[x]) && std::abs(s.y[x] - ridge[x]) <= 1.5;
  EXPECT_GE(good, w * 80 / 100);
}

// A far ridge under a grey veil (haze, flare, an overcast sky's light): a
// faint (about 6 delta E) edge softened over 6 rows under a pale grey sky,
// the slope below as faint as its edge. Faint, soft and colourless as fog
// is, but nothing comes out of the sky's colour below it: not fog (copies of
// the real photos under such a veil were nulled whole). Terrain coming out
// of the same sky over 60 rows below the same edge stays fog.
TEST(ExtractSkyline, FaintRidgeUnderAGreyVeilIsNotFog) {
  const int w = 640, h = 400;
  std::vector<double> ridge(w);
  for (int x = 0; x < w; ++x) ridge[x] = 150.0 + 30.0 * std::sin(x / 70.0) + 9.0 * std::sin(x / 17.0);
  const cv::Vec3d sky(196, 192, 190), veiled(180, 178, 177), clear(70, 105, 85);  // BGR
  auto scene = [&](bool fog) {
    cv::Mat img(h, w, CV_8UC3);
    cv::RNG rng(5);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double t = std::clamp((y + 0.5 - ridge[x]) / 6.0 + 0.5, 0.0, 1.0);  // 0 sky .. 1 ridge, over 6 rows
        const double out = fog ? std::clamp((y + 0.5 - ridge[x]) / 60.0, 0.0, 1.0) : 0.0;  // out of the fog below
        const cv::Vec3d c = (1 - t) * sky + t * ((1 - out) * veiled + out * clear);
        const double n = rng.gaussian(0.8);
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(c[0] + n), cv::saturate_cast<uint8_t>(c[1] + n),
                                            cv::saturate_cast<uint8_t>(c[2] + n));
      }
    return img;
  };
  const Skyline s = ExtractSkyline(scene(false), SkylineOptions{});
  int good = 0;
  for (int x = 0; x < w; ++x) good += std::isfinite(s.y[x]) && std::abs(s.y[x] - ridge[x]) <= 2.0;
  EXPECT_GE(good, w * 80 / 100);
  EXPECT_EQ(ExtractSkyline(scene(true), SkylineOptions{}).VisibleCount(), 0) << "terrain coming out of it is fog";
}

}  // namespace
}  // namespace horizonreg

// Regression guard on rendered dev scenes (scripts/eval_skyline.py prints the
// full table): the share of visible columns within 2 px of the true row.
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "testing/shared_data.h"

namespace horizonreg {
namespace {

double Within2Px(const std::filesystem::path& dir, const std::string& name) {
  const auto t = nlohmann::json::parse(std::ifstream(dir / (name + ".truth.json")));
  const Skyline s = ExtractSkyline(cv::imread((dir / (name + ".jpg")).string()), SkylineOptions{});
  int visible = 0, good = 0;
  for (int c = 0; c < s.width; ++c) {
    const int row = t["skyline_row"][c];
    if (t["occluded"][c] || row <= 0 || row >= s.height) continue;
    ++visible;
    good += std::isfinite(s.y[c]) && std::abs(s.y[c] - row) <= 2.0;
  }
  return visible ? static_cast<double>(good) / visible : 0.0;
}

// A white cumulus floating in the photo's widest sky, as `scripts/eval_real.py
// --modes sky-cloud` paints it: over the quarter of the width whose highest
// traced skyline point leaves the most sky, seven overlapping ellipses in a
// fixed pattern, blurred, their base a third of that sky's height above the
// skyline. Returns the painted columns' range in `from`, `to`.
cv::Mat WithSkyCloud(const cv::Mat& img, const nlohmann::json& rows, int& from, int& to) {
  const int w = img.cols, h = img.rows, k = w / 4;
  const double s = w / 1000.0;
  double best = -1;
  for (int x = 0; x + k <= w; ++x) {
    double top = 1e9;
    for (int c = x; c < x + k; ++c)
      if (!rows[c].is_null()) top = std::min(top, rows[c].get<double>());
    if (top < 1e9 && top > best) best = top, from = x;
  }
  to = from + k;
  const double base = best - std::max(20 * s, best / 3), thick = std::min(36 * s, 0.5 * base);
  cv::Mat mask(h, w, CV_32F, cv::Scalar(0));
  for (int i = 0; i < 7; ++i) {
    const double cx = from + k / 2.0 + (i - 3) / 3.0 * 0.35 * k, cy = base - thick / 2 + (i % 2 ? 0.15 : -0.1) * thick;
    cv::ellipse(mask, cv::Point(static_cast<int>(cx), static_cast<int>(cy)),
                cv::Size(static_cast<int>(0.16 * k), static_cast<int>(0.4 * thick)), 0, 0, 360, cv::Scalar(1.0), -1);
  }
  cv::GaussianBlur(mask, mask, cv::Size(), 4 * s);
  const float cloud[3] = {240.0f, 240.0f, 238.0f};
  cv::Mat out = img.clone();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float a = std::min(0.95f, 1.3f * mask.at<float>(y, x));
      cv::Vec3b& p = out.at<cv::Vec3b>(y, x);
      for (int ch = 0; ch < 3; ++ch) p[ch] = cv::saturate_cast<uint8_t>((1.0f - a) * p[ch] + a * cloud[ch]);
    }
  return out;
}

// Terrain does not float: under a white cumulus in a real photo's sky, the
// skyline stays on the terrain (FindFloatingClouds). Without it the
// boundary ran along the cloud's top in both photos (0 of 243 and 0 of 268
// traced columns within 2 px; with it 208 and 261): snow under a blue sky,
// whose white the histograms learn as ground. Not AK01b_20080811: the sky
// under its cloud departs from the sky model by 3-7 sigmas (haze low over
// the horizon), which reads as a hazy ridge, and 10 of 88 are within 2 px.
TEST(ExtractSkyline, RealPhotosKeepTheirSkylineUnderACloudInTheSky) {
  HR_REQUIRE_SHARED(shared);
  const auto dir = shared / "real" / "columbia";
  for (const char* name : {"AKJNC_20120605_223513", "CG05_20050811_130000"}) {
    const auto t = nlohmann::json::parse(std::ifstream(dir / (std::string(name) + ".truth.json")));
    int from = 0, to = 0;
    const cv::Mat img = WithSkyCloud(cv::imread((dir / (std::string(name) + ".jpg")).string()), t["skyline_row"], from, to);
    const Skyline s = ExtractSkyline(img, SkylineOptions{});
    int traced = 0, good = 0;
    for (int c = from; c < to; ++c) {
      if (t["skyline_row"][c].is_null()) continue;
      ++traced;
      good += std::isfinite(s.y[c]) && std::abs(s.y[c] - t["skyline_row"][c].get<double>()) <= 2.0;
    }
    std::printf("[ skyline ] %-22s under the cloud: %d of %d traced columns within 2 px\n", name, good, traced);
    EXPECT_GE(good, traced * 8 / 10) << name;
  }
}

TEST(ExtractSkyline, DevScenesStayWithinTwoPixels) {
  HR_REQUIRE_SHARED(shared);
  const auto dir = shared / "scenes" / "dev";
  // Measured 98-100% on these (clear, clouds, haze; four DEMs; alps_01's
  // faint far ridge, rainier_00's deep-blue band under the pale sky).
  for (const char* name :
       {"alps_00", "alps_01", "cascades_02", "cascades_03", "fuji_04", "rainier_00", "rainier_01", "zion_01"}) {
    const double share = Within2Px(dir, name);
    std::printf("[ skyline ] %-12s %.1f%% of visible columns within 2 px\n", name, 100 * share);
    EXPECT_GE(share, 0.95) << name;
  }
}

}  // namespace
}  // namespace horizonreg
