// SPDX-License-Identifier: MIT
#include "pipeline/batch.h"

#include "pipeline/position.h"
#include "pipeline/report.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <opencv2/imgcodecs.hpp>

#include "render/render.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

namespace fs = std::filesystem;

class BatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("hr_batch_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir / name) << text; }
  fs::path dir;
};

constexpr char kDemoDem[] = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";
constexpr double kDemoLat = 36.51979713, kDemoLon = -84.16396352;  // the demo's valley floor

// Poses of views where the site's horizon has the most relief (as the demo
// picks them), the best first: every other of the 5-deg steps ranked by the
// spread of the elevation within +-22.5 deg.
std::vector<CameraPose> ReliefPoses(const Site& site, int n) {
  std::vector<std::array<double, 3>> relief;  // std dev, azimuth, mean elevation
  for (double az = 0.0; az < 360.0; az += 5.0) {
    double sum = 0.0, sum2 = 0.0;
    int m = 0;
    for (double d = -22.5; d <= 22.5; d += 0.5, ++m) {
      const double e = site.horizon().ElevationAtDeg(std::fmod(az + d + 360.0, 360.0));
      sum += e, sum2 += e * e;
    }
    relief.push_back({std::sqrt(std::max(0.0, sum2 / m - sum * sum / m / m)), az, sum / m});
  }
  std::sort(relief.rbegin(), relief.rend());
  std::vector<CameraPose> poses;
  for (int i = 0; i < n; ++i) poses.push_back({relief[2 * i][1] + 1.3, relief[2 * i][2] - 4.0, 0.5});
  return poses;
}

TEST_F(BatchTest, ReadsCsvAndJsonManifestsWithStations) {
  Write("stations.csv", "station,lat,lon,agl_m,hfov_deg\ncam1,46.0,8.0,1.7,50\n");
  Write("m.csv", "image,station,lat,lon,alt_m\na.jpg,cam1,,,\nsub/b.jpg,,46.1,8.1,900\n\"c, d.jpg\",cam1,,,\n");
  const auto stations = ReadStations((dir / "stations.csv").string());
  const auto items = ReadManifest((dir / "m.csv").string(), stations);
  ASSERT_EQ(items.size(), 3u);
  EXPECT_EQ(items[0].image, "a.jpg");
  EXPECT_EQ(items[0].image_path, (dir / "a.jpg").string());
  EXPECT_EQ(items[0].lat, 46.0);
  EXPECT_EQ(items[0].agl_m, 1.7);
  EXPECT_EQ(items[0].hfov_deg, 50.0);
  EXPECT_EQ(items[1].alt_m, 900.0);
  EXPECT_EQ(items[2].image, "c, d.jpg");
  Write("m.json", R"({"photos": [{"image": "a.jpg", "lat": 46.0, "lon": 8.0, "initial": "10,1,0,50"}]})");
  const auto j = ReadManifest((dir / "m.json").string());
  ASSERT_EQ(j.size(), 1u);
  ASSERT_TRUE(j[0].initial);
  EXPECT_EQ(j[0].initial->hfov_deg, 50.0);
}

TEST_F(BatchTest, RejectsMalformedManifestsNamingTheLine) {
  const auto error = [&](const std::string& text) -> std::string {
    Write("bad.csv", text);
    try {
      ReadManifest((dir / "bad.csv").string());
    } catch (const InvalidArgument& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(error("image,lat,lon,hfov\na.jpg,1,2,3\n").find("unknown column 'hfov'"), std::string::npos);
  EXPECT_NE(error("image,lat,lon\na.jpg,1,2\na.jpg,1,2\n").find("line 3: image 'a.jpg' is listed twice"), std::string::npos);
  EXPECT_NE(error("image,lat,lon\na.jpg,x,2\n").find("line 2: lat 'x' is not a number"), std::string::npos);
  EXPECT_NE(error("image,lat\na.jpg,1\n").find("lat and lon go together"), std::string::npos);
  EXPECT_NE(error("image,lat,lon\na.jpg,1\n").find("2 cells, the header has 3"), std::string::npos);
  EXPECT_NE(error("image,lat,lon\n").find("no photos"), std::string::npos);
  EXPECT_NE(error("image,lat,lon,agl_m,alt_m\na.jpg,1,2,3,4\n").find("not both"), std::string::npos);
}

// Views rendered from Debian's Jacksboro DEM, registered in parallel on one
// pool with a corrupt and a missing photo among them: every photo once, the
// bad ones as error rows, the others exactly as RegisterPhoto gives them one
// at a time (ThreadSanitizer runs this in CI).
TEST_F(BatchTest, RegistersInParallelLikeOneAtATimeAndTurnsBadPhotosIntoErrorRows) {
  const std::string dem = kDemoDem;
  if (!fs::exists(dem)) GTEST_SKIP() << "python-matplotlib-data is not installed";
  const double lat = kDemoLat, lon = kDemoLon;
  const Site site({dem}, lat, lon, SiteOptions{});
  const auto k = CameraIntrinsics::FromHfov(480, 320, 45.0);
  std::string manifest = "image,lat,lon\n";
  std::vector<cv::Mat> views;
  const std::vector<CameraPose> poses = ReliefPoses(site, 4);
  for (int i = 0; i < 4; ++i) {
    const std::string name = "v" + std::to_string(i) + ".png";
    views.push_back(RenderView(site.window(), site.observer(), poses[i], k, RenderOptions{}));
    cv::imwrite((dir / name).string(), views.back());
    manifest += name + "," + std::to_string(lat) + "," + std::to_string(lon) + "\n";
  }
  Write("corrupt.png", "not a png");
  manifest += "corrupt.png,36.51979713,-84.16396352\nmissing.png,36.51979713,-84.16396352\n";
  Write("m.csv", manifest);
  const auto items = ReadManifest((dir / "m.csv").string());
  BatchOptions o;
  o.dem = {dem};
  o.vouch_stations = false;  // every photo's check as RegisterPhoto's (the vouch: the next test)
  ThreadPool pool(2);
  std::map<std::string, nlohmann::json> rows;
  std::mutex mu;
  size_t progress_calls = 0;
  const size_t n = RunBatch(
      items, o, pool,
      [&](const BatchResult& r) {
        std::lock_guard<std::mutex> lock(mu);
        EXPECT_TRUE(rows.emplace(r.row["image"].get<std::string>(), r.row).second);
      },
      [&](const BatchProgress& p) { progress_calls += p.done <= p.total; });
  ASSERT_EQ(n, items.size());
  ASSERT_EQ(rows.size(), items.size());
  EXPECT_EQ(progress_calls, items.size());
  EXPECT_EQ(rows["corrupt.png"]["status"], "error");
  EXPECT_EQ(rows["missing.png"]["status"], "error");
  const Site alone({dem}, std::stod(std::to_string(lat)), std::stod(std::to_string(lon)), SiteOptions{});
  int registered = 0;
  for (int i = 0; i < 4; ++i) {
    nlohmann::json row = rows["v" + std::to_string(i) + ".png"];
    const PhotoRegistration r = RegisterPhoto(alone, cv::imread((dir / ("v" + std::to_string(i) + ".png")).string()), {});
    nlohmann::json ref = RegistrationReport(alone, r, "arguments", 0.0);
    row.erase("timing_ms"), row.erase("image"), ref.erase("timing_ms");
    EXPECT_EQ(row, ref) << i;
    registered += row["status"] == "registered";
  }
  EXPECT_GE(registered, 2);
}

// A station's photos after two have registered and passed the position
// check skip its wide look: their rows are RegisterPhoto's without it, and
// say who vouched; the first two are RegisterPhoto's own.
TEST_F(BatchTest, AStationVouchedForByTwoPhotosSparesTheRestTheWideLook) {
  if (!fs::exists(kDemoDem)) GTEST_SKIP() << "python-matplotlib-data is not installed";
  const Site site({kDemoDem}, kDemoLat, kDemoLon, SiteOptions{});
  const auto k = CameraIntrinsics::FromHfov(480, 320, 45.0);
  const std::vector<CameraPose> poses = ReliefPoses(site, 4);
  std::string manifest = "image,lat,lon\n";
  for (int i = 0; i < 4; ++i) {
    const std::string name = "v" + std::to_string(i) + ".png";
    cv::imwrite((dir / name).string(), RenderView(site.window(), site.observer(), poses[i], k, RenderOptions{}));
    manifest += name + "," + std::to_string(kDemoLat) + "," + std::to_string(kDemoLon) + "\n";
  }
  Write("m.csv", manifest);
  BatchOptions o;
  o.dem = {kDemoDem};
  ThreadPool pool(2);
  std::map<std::string, nlohmann::json> rows;
  std::mutex mu;
  RunBatch(ReadManifest((dir / "m.csv").string()), o, pool, [&](const BatchResult& r) {
    std::lock_guard<std::mutex> lock(mu);
    rows[r.row["image"].get<std::string>()] = r.row;
  });
  ASSERT_EQ(rows.size(), 4u);
  const Site alone({kDemoDem}, std::stod(std::to_string(kDemoLat)), std::stod(std::to_string(kDemoLon)), SiteOptions{});
  int passed = 0;
  for (int i = 0; i < 4; ++i) {
    nlohmann::json row = rows["v" + std::to_string(i) + ".png"];
    PhotoOptions po;
    const bool light = i >= 2 && passed >= 2;
    if (light) po.check_position->wide_radius_m = 0.0;
    nlohmann::json ref = RegistrationReport(
        alone, RegisterPhoto(alone, cv::imread((dir / ("v" + std::to_string(i) + ".png")).string()), po), "arguments",
        0.0);
    if (light) {
      ASSERT_TRUE(row.contains("position_check")) << i;
      EXPECT_EQ(row["position_check"]["station_vouched_by"], 2) << i;
      EXPECT_EQ(row["position_check"]["wide_places"], 0) << i;
      row["position_check"].erase("station_vouched_by");
    } else {
      EXPECT_FALSE(row.contains("position_check") && row["position_check"].contains("station_vouched_by")) << i;
      passed += row["status"] == "registered" && row.contains("position_check") &&
                row["position_check"]["consistent"] == true;
    }
    row.erase("timing_ms"), row.erase("image"), ref.erase("timing_ms");
    EXPECT_EQ(row, ref) << i;
  }
  EXPECT_EQ(passed, 2);  // the demo's views register and pass: the vouch was exercised
}

// The station camera's opening angle: the photos of the same aspect ratio
// that agree within 2%, at least as many as asked.
TEST(AgreedOpeningAngle, TheMedianOfAgreeingPhotosOfTheSameAspect) {
  const std::vector<std::pair<double, double>> views = {{51.0, 1.5}, {51.6, 1.5}, {51.3, 1.502}, {38.0, 1.0}};
  EXPECT_DOUBLE_EQ(*AgreedOpeningAngle(views, 1.5, 2), 51.3);
  EXPECT_DOUBLE_EQ(*AgreedOpeningAngle(views, 1.5, 3), 51.3);
  EXPECT_FALSE(AgreedOpeningAngle(views, 1.5, 4));          // too few of that aspect
  EXPECT_FALSE(AgreedOpeningAngle(views, 1.0, 2));          // one portrait photo
  EXPECT_FALSE(AgreedOpeningAngle(views, 4.0 / 3.0, 1));    // none of that aspect
  EXPECT_DOUBLE_EQ(*AgreedOpeningAngle(views, 1.0, 1), 38.0);
  EXPECT_FALSE(AgreedOpeningAngle({{40.0, 1.5}, {41.0, 1.5}}, 1.5, 2));  // 2.5% apart: the zoom moved
  EXPECT_DOUBLE_EQ(*AgreedOpeningAngle({{40.0, 1.5}, {40.7, 1.5}}, 1.5, 2), 40.0);
}

// --refine-position in a batch: each row is register --refine-position's
// report (the "position" block included), and the CSV carries the refined
// position.
TEST_F(BatchTest, RefinesEachPhotosPositionWhenAsked) {
  if (!fs::exists(kDemoDem)) GTEST_SKIP() << "python-matplotlib-data is not installed";
  const Site site({kDemoDem}, kDemoLat, kDemoLon, SiteOptions{});
  const CameraPose pose = ReliefPoses(site, 1)[0];
  cv::imwrite((dir / "v.png").string(), RenderView(site.window(), site.observer(), pose,
                                                   CameraIntrinsics::FromHfov(480, 320, 45.0), RenderOptions{}));
  Write("m.csv", "image,lat,lon\nv.png," + std::to_string(kDemoLat) + "," + std::to_string(kDemoLon) + "\n");
  BatchOptions o;
  o.dem = {kDemoDem};
  o.refine_position = true;
  ThreadPool pool(2);
  nlohmann::json row;
  RunBatch(ReadManifest((dir / "m.csv").string()), o, pool, [&](const BatchResult& r) { row = r.row; });
  ASSERT_TRUE(row.contains("position")) << row.dump();
  const Site alone({kDemoDem}, std::stod(std::to_string(kDemoLat)), std::stod(std::to_string(kDemoLon)), SiteOptions{});
  PhotoOptions po;
  po.refine_position = DefaultPositionOptions("arguments", false, std::nullopt);
  nlohmann::json ref =
      RegistrationReport(alone, RegisterPhoto(alone, cv::imread((dir / "v.png").string()), po), "arguments", 0.0);
  row.erase("timing_ms"), row.erase("image"), ref.erase("timing_ms");
  EXPECT_EQ(row, ref);
  const std::string header = BatchCsvHeader(), line = BatchCsvLine(row);
  EXPECT_NE(header.find(",refined_lat,refined_lon,refined_eye_height_m"), std::string::npos);
  EXPECT_EQ(std::count(line.begin(), line.end(), ','), std::count(header.begin(), header.end(), ','));
  EXPECT_EQ(line.substr(line.rfind(',') + 1), nlohmann::json(row["position"]["eye_height_m"]).dump());

  o.photo.position_sigma_m = 0.0;
  EXPECT_THROW(o.Check(), InvalidArgument);
}

// skylines: each row carries the photo's skyline, RegisteredSkyline's at the
// row's registration (one per column, the image's size); without it, none.
TEST_F(BatchTest, CarriesEachPhotosSkylineWhenAsked) {
  if (!fs::exists(kDemoDem)) GTEST_SKIP() << "python-matplotlib-data is not installed";
  const Site site({kDemoDem}, std::stod(std::to_string(kDemoLat)), std::stod(std::to_string(kDemoLon)), SiteOptions{});
  // The first of the relief views that registers.
  const auto k = CameraIntrinsics::FromHfov(480, 320, 45.0);
  cv::Mat image;
  PhotoRegistration r;
  for (const CameraPose& pose : ReliefPoses(site, 4)) {
    image = RenderView(site.window(), site.observer(), pose, k, RenderOptions{});
    r = RegisterPhoto(site, image, {});
    if (r.registration.registered) break;
  }
  ASSERT_TRUE(r.registration.registered);
  cv::imwrite((dir / "v.png").string(), image);
  Write("m.csv", "image,lat,lon\nv.png," + std::to_string(kDemoLat) + "," + std::to_string(kDemoLon) + "\n");
  BatchOptions o;
  o.dem = {kDemoDem};
  ThreadPool pool(2);
  nlohmann::json plain, with;
  RunBatch(ReadManifest((dir / "m.csv").string()), o, pool, [&](const BatchResult& b) { plain = b.row; });
  o.skylines = true;
  RunBatch(ReadManifest((dir / "m.csv").string()), o, pool, [&](const BatchResult& b) { with = b.row; });
  EXPECT_FALSE(plain.contains("skyline"));
  ASSERT_TRUE(with.contains("skyline")) << with.dump();
  EXPECT_EQ(with["status"], "registered") << with["message"];
  EXPECT_EQ(with["skyline"], SkylineJson(RegisteredSkyline(site, image, r)));
  EXPECT_EQ(with["skyline"]["width"], 480);
  EXPECT_EQ(with["skyline"]["y"].size(), 480u);
  EXPECT_GT(with["skyline"]["visible_columns"].get<int>(), 400);
  with.erase("skyline");
  with.erase("timing_ms"), plain.erase("timing_ms");
  EXPECT_EQ(with, plain);  // the rest of the row is unchanged
}

}  // namespace
}  // namespace horizonreg
