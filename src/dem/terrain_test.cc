// SPDX-License-Identifier: MIT
#include "dem/terrain.h"

#include <gdal.h>
#include <gtest/gtest.h>
#include <ogr_srs_api.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "testing/shared_data.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() {
  fs::path d = fs::temp_directory_path() / ("horizonreg_dem_test_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

// Writes a small WGS84 GeoTIFF with the given values (row 0 north).
void WriteTiff(const fs::path& path, int w, int h, double west, double north, double step,
               const std::vector<float>& values, std::optional<double> nodata) {
  GDALAllRegister();
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), path.c_str(), w, h, 1, GDT_Float32, nullptr);
  double gt[6] = {west - step / 2, step, 0, north + step / 2, 0, -step};
  GDALSetGeoTransform(ds, gt);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRSetWellKnownGeogCS(srs, "WGS84");
  GDALSetSpatialRef(ds, srs);
  OSRDestroySpatialReference(srs);
  GDALRasterBandH b = GDALGetRasterBand(ds, 1);
  if (nodata) GDALSetRasterNoDataValue(b, *nodata);
  EXPECT_EQ(GDALRasterIO(b, GF_Write, 0, 0, w, h, const_cast<float*>(values.data()), w, h, GDT_Float32, 0, 0), CE_None);
  GDALClose(ds);
}

TEST(Terrain, ReadsASyntheticGeoTiffExactlyAtPostsAndBilinearBetween) {
  const fs::path p = TempDir() / "ramp.tif";
  std::vector<float> v(10 * 8);
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 10; ++c) v[r * 10 + c] = static_cast<float>(100 * c + 10 * r);
  WriteTiff(p, 10, 8, 7.0, 46.0, 0.01, v, std::nullopt);
  Terrain t({p.string()});
  TerrainWindow w = t.ReadWindow({45.97, 7.04, 0}, 5000.0);
  ASSERT_EQ(w.grids.size(), 1u);
  EXPECT_NEAR(*w.HeightAt(46.0, 7.0), 0.0, 1e-3);
  EXPECT_NEAR(*w.HeightAt(45.98, 7.03), 300 + 20, 1e-3);
  // Half-way between posts: the bilinear mean.
  EXPECT_NEAR(*w.HeightAt(45.975, 7.035), 350 + 25, 1e-3);
  EXPECT_FALSE(w.HeightAt(46.5, 7.0).has_value());
}

TEST(Terrain, FillsVoidsByInterpolation) {
  const fs::path p = TempDir() / "void.tif";
  std::vector<float> v(9 * 9, 500.0f);
  v[4 * 9 + 4] = -9999.0f;  // one void in the middle
  WriteTiff(p, 9, 9, 10.0, 45.0, 0.01, v, -9999.0);
  Terrain t({p.string()});
  TerrainWindow w = t.ReadWindow({44.96, 10.04, 0}, 20000.0);
  EXPECT_NEAR(*w.HeightAt(44.96, 10.04), 500.0, 1e-3);
}

TEST(Terrain, AllVoidDemIsAnInvalidArgument) {
  const fs::path p = TempDir() / "allvoid.tif";
  WriteTiff(p, 5, 5, 10.0, 45.0, 0.01, std::vector<float>(25, -9999.0f), -9999.0);
  Terrain t({p.string()});
  EXPECT_THROW(t.ReadWindow({44.98, 10.02, 0}, 1000.0), InvalidArgument);
}

TEST(Terrain, BadFilesAreIoErrorsNamingTheFile) {
  const fs::path dir = TempDir();
  try {
    Terrain t({(dir / "missing.hgt").string()});
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.hgt"), std::string::npos);
  }
  std::ofstream(dir / "notes.txt") << "this is not a raster\n";
  EXPECT_THROW(Terrain({(dir / "notes.txt").string()}), IoError);
  EXPECT_THROW(Terrain({dir.string()}), IoError);
  EXPECT_THROW(Terrain(std::vector<std::string>{}), InvalidArgument);
}

TEST(Terrain, ObserverOutsideEveryDemIsAnInvalidArgument) {
  const fs::path p = TempDir() / "small.tif";
  WriteTiff(p, 5, 5, 10.0, 45.0, 0.01, std::vector<float>(25, 1.0f), std::nullopt);
  Terrain t({p.string()});
  EXPECT_TRUE(t.Covers(44.98, 10.02));
  EXPECT_FALSE(t.Covers(44.0, 10.02));
  EXPECT_THROW(t.ReadWindow({44.0, 10.02, 0}, 1000.0), InvalidArgument);
}

TEST(Terrain, EveryDemInSharedLoads) {
  HR_REQUIRE_SHARED(shared);
  int count = 0;
  for (const auto& entry : fs::directory_iterator(shared / "dem")) {
    if (entry.path().extension() == ".md" || entry.path().extension() == ".xml")
      continue;  // notes, GDAL .aux.xml sidecars
    SCOPED_TRACE(entry.path().string());
    Terrain t({entry.path().string()});
    const GeodeticPoint c = t.CenterOf(0);
    TerrainWindow w = t.ReadWindow(c, 10000.0);
    ASSERT_FALSE(w.grids.empty());
    const auto h = w.HeightAt(c.lat_deg, c.lon_deg);
    ASSERT_TRUE(h.has_value());
    EXPECT_GT(*h, -100.0);
    EXPECT_LT(*h, 9000.0);
    ++count;
  }
  EXPECT_GE(count, 16);  // every file SOURCES.md lists
}

TEST(Terrain, ProjectedUsgsDemGivesMountStHelensSummitHeight) {
  HR_REQUIRE_SHARED(shared);
  Terrain t({(shared / "dem" / "SainteHelens.dem").string()});
  TerrainWindow w = t.ReadWindow({46.2, -122.19, 0}, 8000.0);
  ASSERT_EQ(w.grids.size(), 1u);
  EXPECT_FALSE(w.grids[0].separable);
  double top = 0;
  for (float v : w.grids[0].height_m) top = std::max<double>(top, v);
  EXPECT_GT(top, 2400.0);  // the crater rim, 2549 m after 1980
  EXPECT_LT(top, 2600.0);
}

TEST(Terrain, AdjacentSrtmTilesFormOneContinuousMosaic) {
  HR_REQUIRE_SHARED(shared);
  const std::string a = (shared / "dem" / "N41E001.hgt").string(), b = (shared / "dem" / "N42E001.hgt").string();
  Terrain both({a, b});
  TerrainWindow w = both.ReadWindow({42.0, 1.5, 0}, 20000.0);
  ASSERT_EQ(w.grids.size(), 1u);  // one grid across the tile edge
  Terrain south({a}), north({b});
  const auto hs = south.ReadWindow({41.99, 1.5, 0}, 3000.0).HeightAt(42.0, 1.5);
  const auto hn = north.ReadWindow({42.01, 1.5, 0}, 3000.0).HeightAt(42.0, 1.5);
  ASSERT_TRUE(hs && hn);
  EXPECT_NEAR(*hs, *hn, 1e-3);  // SRTM tiles share their edge posts
  EXPECT_NEAR(*w.HeightAt(42.0, 1.5), *hs, 1e-3);
  EXPECT_TRUE(w.HeightAt(42.15, 1.5).has_value());
  EXPECT_TRUE(w.HeightAt(41.85, 1.5).has_value());
}

TEST(Terrain, FilledVoidsLeaveNoHolesInRainier) {
  HR_REQUIRE_SHARED(shared);
  Terrain t({(shared / "dem" / "mt_rainier_90m.tif").string()});
  TerrainWindow w = t.ReadWindow({46.5, -121.5, 0}, 200000.0);
  size_t nan = 0;
  for (float v : w.grids[0].height_m) nan += !std::isfinite(v);
  EXPECT_EQ(nan, 0u);
}

TEST(Terrain, ReadsTheMatplotlibJacksboroNpz) {
  const char* path = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";
  if (!fs::exists(path)) GTEST_SKIP() << "SKIPPED: python-matplotlib-data is not installed";
  Terrain t({path});
  const GeodeticPoint c = t.CenterOf(0);
  EXPECT_NEAR(c.lat_deg, (36.733 + 36.447) / 2, 0.05);
  TerrainWindow w = t.ReadWindow(c, 100000.0);
  ASSERT_EQ(w.grids.size(), 1u);
  EXPECT_EQ(w.grids[0].width, 403);
  EXPECT_EQ(w.grids[0].height, 344);
  EXPECT_GT(w.grids[0].lat0_deg, w.grids[0].LatAt(0, 343));  // row 0 is the northern row
  float lo = 1e9f, hi = -1e9f;
  for (float v : w.grids[0].height_m) lo = std::min(lo, v), hi = std::max(hi, v);
  EXPECT_NEAR(lo, 236, 5);
  EXPECT_NEAR(hi, 1076, 5);
}

// A grid of 4 x 3 posts, 0.01 deg apart from (45.0, 7.0), separable or
// with every post's position (a projected grid's form).
DemGrid SmallGrid(bool separable) {
  DemGrid g;
  g.width = 4, g.height = 3;
  g.height_m.assign(12, 100.0f);
  g.separable = separable;
  g.lat0_deg = 45.0, g.dlat_deg = -0.01, g.lon0_deg = 7.0, g.dlon_deg = 0.01;
  if (!separable) {
    for (int r = 0; r < g.height; ++r)
      for (int c = 0; c < g.width; ++c) g.lat_deg.push_back(45.0 - 0.01 * r), g.lon_deg.push_back(7.0 + 0.01 * c);
    g.IndexPositions();
  }
  return g;
}

TEST(WithPostTrig, IndexesACopyOfTheProjectedGridsOnly) {
  TerrainWindow w;
  w.grids.push_back(SmallGrid(true));
  EXPECT_FALSE(WithPostTrig(w).has_value());  // nothing to index
  w.grids.push_back(SmallGrid(false));
  const std::optional<TerrainWindow> indexed = WithPostTrig(w);
  ASSERT_TRUE(indexed.has_value());
  ASSERT_EQ(indexed->grids.size(), 2u);
  EXPECT_TRUE(indexed->grids[0].post_trig.empty());
  ASSERT_EQ(indexed->grids[1].post_trig.size(), 4u * 12u);
  EXPECT_TRUE(w.grids[1].post_trig.empty());  // the given window is left as it was
  // Post (row 2, column 3): sin and cos of its latitude and longitude.
  const double* t = indexed->grids[1].post_trig.data() + 4 * (2 * 4 + 3);
  EXPECT_NEAR(t[0], std::sin(DegToRad(44.98)), 1e-15);
  EXPECT_NEAR(t[1], std::cos(DegToRad(44.98)), 1e-15);
  EXPECT_NEAR(t[2], std::sin(DegToRad(7.03)), 1e-15);
  EXPECT_NEAR(t[3], std::cos(DegToRad(7.03)), 1e-15);
  EXPECT_EQ(indexed->HeightAt(44.995, 7.015), w.HeightAt(44.995, 7.015));
  EXPECT_FALSE(WithPostTrig(*indexed).has_value());  // already indexed
  EXPECT_FALSE(WithPostTrig(w, 23).has_value());     // 24 posts: more than allowed
  EXPECT_TRUE(WithPostTrig(w, 24).has_value());
}

}  // namespace
}  // namespace horizonreg
