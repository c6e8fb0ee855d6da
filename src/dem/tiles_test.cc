// SPDX-License-Identifier: MIT
#include "dem/tiles.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "util/errors.h"

namespace horizonreg {
namespace {

namespace fs = std::filesystem;

TEST(HgtNameExtent, ReadsSrtmTileNames) {
  GeoBox b;
  ASSERT_TRUE(HgtNameExtent("/x/N47E009.hgt", b));
  EXPECT_EQ(b.south, 47.0);
  EXPECT_EQ(b.north, 48.0);
  EXPECT_EQ(b.west, 9.0);
  EXPECT_EQ(b.east, 10.0);
  ASSERT_TRUE(HgtNameExtent("s12w077.HGT", b));
  EXPECT_EQ(b.south, -12.0);
  EXPECT_EQ(b.west, -77.0);
  for (const char* bad : {"N47E009.tif", "X47E009.hgt", "N47E009x.hgt", "N4E009.hgt", "N95E009.hgt", "dem.hgt"})
    EXPECT_FALSE(HgtNameExtent(bad, b)) << bad;
}

// A folder of SRTM tile names (found by name, not opened).
class TileFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("hr_tiles_" + std::to_string(::getpid()));
    fs::create_directories(dir / "sub");
    for (const char* n : {"N41E001.hgt", "N42E001.hgt", "sub/N42E002.hgt", "N10E010.hgt"}) std::ofstream(dir / n) << "x";
    std::ofstream(dir / "notes.txt") << "not a DEM";
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
};

TEST_F(TileFolder, PicksTheTilesWithinTheRadius) {
  const DemTileIndex index(dir.string());
  EXPECT_EQ(index.tiles().size(), 4u);
  auto names = [](const std::vector<std::string>& v) {
    std::vector<std::string> out;
    for (const auto& p : v) out.push_back(fs::path(p).filename().string());
    return out;
  };
  // 2 km north of the 42 N edge, 20 km from 2 E: the two tiles of that edge...
  EXPECT_EQ(names(index.TilesAround(42.02, 1.8, 10'000.0)), (std::vector<std::string>{"N41E001.hgt", "N42E001.hgt"}));
  // ...and with 30 km the eastern neighbour too; never the far tile.
  EXPECT_EQ(names(index.TilesAround(42.02, 1.8, 30'000.0)),
            (std::vector<std::string>{"N41E001.hgt", "N42E001.hgt", "N42E002.hgt"}));
  EXPECT_EQ(names(index.TilesAround(42.5, 1.5, 5'000.0)), (std::vector<std::string>{"N42E001.hgt"}));
  EXPECT_THROW(index.TilesAround(30.0, 1.5, 5'000.0), InvalidArgument);  // no tile covers the position
  EXPECT_EQ(DemFilesFor({}, dir.string(), 42.5, 1.5, 5'000.0).size(), 1u);
  EXPECT_EQ(DemFilesFor({"a.tif"}, "", 42.5, 1.5, 5'000.0), (std::vector<std::string>{"a.tif"}));
  EXPECT_THROW(DemFilesFor({"a.tif"}, dir.string(), 42.5, 1.5, 5'000.0), InvalidArgument);
  EXPECT_THROW(DemFilesFor({}, "", 42.5, 1.5, 5'000.0), InvalidArgument);
}

TEST_F(TileFolder, RejectsAFolderWithoutDemsAndAFile) {
  EXPECT_THROW(DemTileIndex((dir / "notes.txt").string()), IoError);
  const fs::path empty = dir / "empty";
  fs::create_directories(empty);
  EXPECT_THROW(DemTileIndex(empty.string()), IoError);
}

TEST(AddSeaLevel, CoversTheRadiusAtZeroMetres) {
  TerrainWindow w;
  AddSeaLevel(w, {60.0, 5.0, 0.0}, 50'000.0);
  ASSERT_EQ(w.grids.size(), 1u);
  for (double dlat : {-0.44, 0.0, 0.44})
    for (double dlon : {-0.89, 0.0, 0.89}) {
      const auto h = w.HeightAt(60.0 + dlat, 5.0 + dlon);
      ASSERT_TRUE(h) << dlat << " " << dlon;
      EXPECT_EQ(*h, 0.0);
    }
}

}  // namespace
}  // namespace horizonreg
