// SPDX-License-Identifier: MIT
#include "overlay/overlay.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "testing/synthetic_dem.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(OverlayOptions, DefaultsAreValid) { EXPECT_NO_THROW(OverlayOptions{}.Check()); }
TEST(LandmarkOptions, DefaultsAreValid) { EXPECT_NO_THROW(LandmarkOptions{}.Check()); }

HorizonProfile FlatHorizon() {
  HorizonProfile p;
  p.azimuth_step_deg = 0.25;
  p.elevation_deg.assign(1440, 0.5);
  p.distance_m.assign(1440, 20000.0);
  p.lat_deg.assign(1440, 0.0);
  p.lon_deg.assign(1440, 0.0);
  p.height_m.assign(1440, 0.0);
  return p;
}

TEST(DrawOverlay, LandmarkLandsOnItsPixel) {
  const HorizonProfile h = FlatHorizon();
  const CameraPose pose{100.0, 2.0, 3.0};
  const auto k = CameraIntrinsics::FromHfov(800, 500, 40.0);
  ResolvedLandmark l;
  l.name = "Test Peak";
  l.azimuth_deg = 104.0;
  l.elevation_deg = 1.0;
  l.distance_m = 12000.0;
  l.height_m = 2000.0;
  l.visible = true;
  OverlayInput in{&h, nullptr, {l}};
  const OverlayResult r = DrawOverlay(cv::Mat(500, 800, CV_8UC3, cv::Scalar(90, 140, 90)), pose, k, in, {});
  ASSERT_EQ(r.labels.size(), 1u);
  const auto expected = ProjectAzEl(CamFromEnu(pose), k, 104.0, 1.0);
  EXPECT_NEAR(r.labels[0].x, expected->x(), 1e-9);
  EXPECT_NEAR(r.labels[0].y, expected->y(), 1e-9);
  // Independent check: 4 deg right of the axis, 1 deg below it, rotated by the roll.
  const double f = k.focal_px;
  const double x0 = f * std::tan(DegToRad(4.0)), y0 = f * std::tan(DegToRad(1.0));  // approximately, level camera
  const double rr = DegToRad(3.0);
  EXPECT_NEAR(r.labels[0].x - k.cx_px, x0 * std::cos(rr) + y0 * std::sin(rr), 4.0);
  EXPECT_NEAR(r.labels[0].y - k.cy_px, y0 * std::cos(rr) - x0 * std::sin(rr), 4.0);
  EXPECT_NE(r.labels[0].text.find("Test Peak"), std::string::npos);
  EXPECT_NE(r.labels[0].text.find("12.0 km"), std::string::npos);
}

TEST(DrawOverlay, HiddenOrOutOfViewLandmarksAreNotDrawn) {
  const HorizonProfile h = FlatHorizon();
  ResolvedLandmark hidden;
  hidden.name = "Hidden";
  hidden.azimuth_deg = 100.0;
  hidden.visible = false;
  ResolvedLandmark behind = hidden;
  behind.name = "Behind";
  behind.azimuth_deg = 280.0;
  behind.visible = true;
  OverlayInput in{&h, nullptr, {hidden, behind}};
  const auto k = CameraIntrinsics::FromHfov(640, 400, 50.0);
  const OverlayResult r = DrawOverlay(cv::Mat(400, 640, CV_8UC3, cv::Scalar(0)), {100, 0, 0}, k, in, {});
  EXPECT_TRUE(r.labels.empty());
}

// Row of the yellow artificial horizon in a column (centroid of yellowness;
// pixel centres at r + 0.5).
double YellowRow(const cv::Mat& img, int col) {
  double sum = 0, n = 0;
  for (int r = 0; r < img.rows; ++r) {
    const cv::Vec3b v = img.at<cv::Vec3b>(r, col);
    const double w = std::max(0, std::min(v[1], v[2]) - v[0]);
    sum += w * (r + 0.5), n += w;
  }
  return n > 0 ? sum / n : NAN;
}

TEST(DrawOverlay, ArtificialHorizonFollowsRoll) {
  const HorizonProfile h = FlatHorizon();
  OverlayOptions o;
  o.horizon = o.ground_grid = o.compass = o.readout = o.vertical_axis = o.landmarks = false;
  const auto k = CameraIntrinsics::FromHfov(800, 600, 50.0);
  OverlayInput in{&h, nullptr, {}};
  const cv::Mat black(600, 800, CV_8UC3, cv::Scalar(0));
  const cv::Mat level = DrawOverlay(black, {30, 0, 0}, k, in, o).image;
  EXPECT_NEAR(YellowRow(level, 100), 300.0, 1.5);
  EXPECT_NEAR(YellowRow(level, 700), 300.0, 1.5);
  // Roll +5 deg (right side down): the scene turns anticlockwise, so the
  // horizon rises on the right... in image y (down) it goes up on the left.
  const cv::Mat rolled = DrawOverlay(black, {30, 0, 5}, k, in, o).image;
  const double left = YellowRow(rolled, 100), right = YellowRow(rolled, 700);
  EXPECT_NEAR((left - right) / 600.0, std::tan(DegToRad(5.0)), 0.01);
  // Pitch up 3 deg: the horizon moves down by f tan(3 deg).
  const cv::Mat up = DrawOverlay(black, {30, 3, 0}, k, in, o).image;
  EXPECT_NEAR(YellowRow(up, 400), 300.0 + k.focal_px * std::tan(DegToRad(3.0)), 1.5);
}

TEST(LoadLandmarks, ReadsGeoJsonAndCsvAndRejectsGarbage) {
  const auto dir = std::filesystem::temp_directory_path();
  const auto gj = dir / "hr_landmarks.geojson", csv = dir / "hr_landmarks.csv", bad = dir / "hr_bad.csv";
  std::ofstream(gj)
      << R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{"name":"A","ele":1234},
    "geometry":{"type":"Point","coordinates":[8.5,46.5]}}]})";
  std::ofstream(csv) << "name,lat,lon,ele\n\"Peak, North\",46.6,8.4,3000\nB,46.7,8.3\n";
  std::ofstream(bad) << "A,46.6,8.1\nB,46.6,eight\n";
  const auto a = LoadLandmarks(gj.string());
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].name, "A");
  EXPECT_NEAR(a[0].lat_deg, 46.5, 1e-12);
  EXPECT_NEAR(*a[0].ele_m, 1234.0, 1e-12);
  const auto b = LoadLandmarks(csv.string());
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b[0].name, "Peak, North");
  EXPECT_FALSE(b[1].ele_m);
  EXPECT_THROW(LoadLandmarks(bad.string()), InvalidArgument);
  EXPECT_THROW(LoadLandmarks((dir / "hr_nonexistent.csv").string()), IoError);
  std::filesystem::remove(gj), std::filesystem::remove(csv), std::filesystem::remove(bad);
}

TEST(ResolveLandmarks, SnapsToTheSummitAndFindsOcclusion) {
  // Cones north of the observer (summits at base + height): a 1900 m one 5 km
  // away hides an 1800 m one 10 km away; a 1600 m one to the north-east.
  auto near = testing::ConeHeight(46.045, 8.0, 400.0, 1500.0, 1500.0);
  auto far = testing::ConeHeight(46.09, 8.0, 400.0, 1400.0, 1500.0);
  auto east = testing::ConeHeight(46.03, 8.06, 400.0, 1200.0, 1000.0);
  DemGrid g = testing::SynthesizeDem(46.15, 7.9, 1.0 / 3600, 800, 600, [&](double lat, double lon) {
    return std::max({near(lat, lon), far(lat, lon), east(lat, lon)});
  });
  const TerrainWindow w = testing::WindowOf(std::move(g));
  const GeodeticPoint eye = ResolveObserver(w, 46.0, 8.0, 1.7, std::nullopt);
  const auto r = ResolveLandmarks(w, eye,
                                  {{"Near", 46.047, 8.002, 1900.0},
                                   {"Far", 46.09, 8.0, 1800.0},
                                   {"East", 46.031, 8.061, std::nullopt},
                                   {"Outside", 10.0, 10.0, std::nullopt}},
                                  {});
  ASSERT_EQ(r.size(), 3u);
  EXPECT_TRUE(r[0].visible);
  EXPECT_NEAR(r[0].height_m, 1900.0, 25.0);  // snapped from 250 m away
  EXPECT_NEAR(r[0].lat_deg, 46.045, 0.0006);
  EXPECT_FALSE(r[1].visible);
  EXPECT_TRUE(r[2].visible);
  EXPECT_NEAR(r[2].azimuth_deg, 54.0, 2.0);
}

// A no_match's reason is drawn in full: lines that fit the width, the text
// given back when they are joined, and an ellipsis only past max_lines.
TEST(WrapText, BreaksAtSpacesWithinTheWidth) {
  const std::string text =
      "no match: ambiguous: another pose fits almost as well (cost ratio 1.31); a second look, 70 columns re-read "
      "near the DEM horizon: the re-read skyline does not register on its own";
  auto width = [](const std::string& s) {
    int base = 0;
    return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, 0.6, 4, &base).width;
  };
  ASSERT_GT(width(text), 980);  // one line would run past a 1000 px image
  const std::vector<std::string> lines = WrapText(text, 0.6, 4, 980, 8);
  ASSERT_GE(lines.size(), 2u);
  std::string joined;
  for (const std::string& l : lines) {
    EXPECT_LE(width(l), 980) << l;
    joined += (joined.empty() ? "" : " ") + l;
  }
  EXPECT_EQ(joined, text);
  const std::vector<std::string> two = WrapText(text, 0.6, 4, 300, 2);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[1].substr(two[1].size() - 4), " ...");
  EXPECT_EQ(WrapText("short", 0.6, 4, 980, 8), std::vector<std::string>{"short"});
  EXPECT_TRUE(WrapText("  ", 0.6, 4, 980, 8).empty());
  // A word wider than the line gets a line of its own.
  EXPECT_EQ(WrapText("a " + std::string(200, 'x') + " b", 0.6, 4, 100, 8).size(), 3u);
  EXPECT_THROW(WrapText(text, 0.6, 4, 980, 0), InvalidArgument);
}

}  // namespace
}  // namespace horizonreg
