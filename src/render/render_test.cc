// SPDX-License-Identifier: MIT
#include "render/render.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "horizon/horizon.h"
#include "match/register.h"
#include "testing/synthetic_dem.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(RenderOptions, DefaultsAreValid) { EXPECT_NO_THROW(RenderOptions{}.Check()); }

// First non-sky row per column of a flat-sky render, NaN if none.
std::vector<double> SkyEdge(const cv::Mat& img) {
  std::vector<double> rows(img.cols, NAN);
  for (int c = 0; c < img.cols; ++c)
    for (int r = 0; r < img.rows; ++r)
      if (img.at<cv::Vec3b>(r, c) != cv::Vec3b(255, 0, 255)) {
        rows[c] = r;
        break;
      }
  return rows;
}

struct ConeScene {
  TerrainWindow window;
  GeodeticPoint eye;
};

ConeScene Cone() {
  // A 2500 m cone 12 km north-east of the observer on a 500 m plain; 3" posts.
  const double lat0 = 46.0, lon0 = 8.0;
  DemGrid g = testing::SynthesizeDem(46.25, 7.75, 1.0 / 1200, 601, 601,
                                     testing::ConeHeight(46.08, 8.11, 500.0, 2500.0, 6000.0));
  ConeScene s{testing::WindowOf(std::move(g)), {}};
  s.eye = ResolveObserver(s.window, lat0, lon0, 1.7, std::nullopt);
  return s;
}

TEST(RenderView, SkylineAgreesWithTheProjectedHorizon) {
  const ConeScene s = Cone();
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.05;
  ho.max_distance_m = 30'000.0;
  const HorizonProfile p = ComputeHorizon(s.window, s.eye, ho);
  const CameraPose pose{44.0, 3.0, 2.0};
  const auto k = CameraIntrinsics::FromHfov(640, 400, 40.0);
  RenderOptions ro;
  ro.flat_sky = true;
  ro.max_distance_m = 30'000.0;
  const cv::Mat img = RenderView(s.window, s.eye, pose, k, ro);
  ASSERT_EQ(img.cols, 640);
  ASSERT_EQ(img.rows, 400);
  const auto edge = SkyEdge(img);
  const auto expected = ProjectedHorizonRows(p, pose, k);
  int compared = 0, close = 0;
  for (int c = 0; c < k.width; ++c) {
    if (!std::isfinite(expected[c]) || expected[c] < 1 || expected[c] > k.height - 1) continue;
    ++compared;
    close += std::abs(edge[c] - expected[c]) <= 1.0;
  }
  EXPECT_GT(compared, 500);
  EXPECT_GE(close, 0.97 * compared) << close << " of " << compared;
}

TEST(RenderView, LookingUpShowsOnlySkyAndDownOnlyTerrain) {
  const ConeScene s = Cone();
  RenderOptions ro;
  ro.flat_sky = true;
  const auto k = CameraIntrinsics::FromHfov(64, 48, 30.0);
  const cv::Mat up = RenderView(s.window, s.eye, {200.0, 80.0, 0.0}, k, ro);
  for (int r = 0; r < up.rows; ++r)
    for (int c = 0; c < up.cols; ++c) ASSERT_EQ(up.at<cv::Vec3b>(r, c), cv::Vec3b(255, 0, 255));
  const cv::Mat down = RenderView(s.window, s.eye, {200.0, -60.0, 0.0}, k, ro);
  for (int r = 0; r < down.rows; ++r)
    for (int c = 0; c < down.cols; ++c) ASSERT_NE(down.at<cv::Vec3b>(r, c), cv::Vec3b(255, 0, 255));
}

TEST(RenderPanorama, ConeStandsAtItsAzimuth) {
  const ConeScene s = Cone();
  RenderOptions ro;
  ro.flat_sky = true;
  const cv::Mat pano = RenderPanorama(s.window, s.eye, 720, 200, -5.0, 15.0, ro);
  const auto edge = SkyEdge(pano);
  const int top = static_cast<int>(std::min_element(edge.begin(), edge.end()) - edge.begin());
  // The cone's summit bears ~42.4 deg (46.08 N, 8.11 E from 46 N, 8 E).
  EXPECT_NEAR(top * 0.5 + 0.25, 42.4, 1.5);
  EXPECT_THROW(RenderPanorama(s.window, s.eye, 4, 4, 0, 1, ro), InvalidArgument);
}

}  // namespace
}  // namespace horizonreg
