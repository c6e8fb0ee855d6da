// SPDX-License-Identifier: MIT
// --dem-dir over the real DEM folder ../shared/dem: the right files by position.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "dem/tiles.h"
#include "testing/shared_data.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

std::vector<std::string> Names(const std::vector<std::string>& v) {
  std::vector<std::string> out;
  for (const auto& p : v) out.push_back(std::filesystem::path(p).filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(DemTileIndex, PicksTheSharedDemsByPosition) {
  HR_REQUIRE_SHARED(shared);
  const DemTileIndex index((shared / "dem").string());
  EXPECT_GE(index.tiles().size(), 18u);  // every file of the folder, any format
  using V = std::vector<std::string>;
  EXPECT_EQ(Names(index.TilesAround(42.02, 1.8, 10'000.0)), (V{"N41E001.hgt", "N42E001.hgt"}));  // Pyrenees edge
  EXPECT_EQ(Names(index.TilesAround(47.25, 9.35, 50'000.0)), (V{"N47E009.hgt"}));               // Saentis
  EXPECT_EQ(Names(index.TilesAround(61.2, -147.0, 30'000.0)), (V{"dem_Columbia.tif"}));        // projected GeoTIFF
  // Mount St. Helens (UTM USGS DEM) reaches the Rainier GeoTIFF within 50 km.
  EXPECT_EQ(Names(index.TilesAround(46.2, -122.18, 50'000.0)), (V{"SainteHelens.dem", "mt_rainier_90m.tif"}));
  // The DTED tile and its 1-degree USGS DEM copy cover the same ground.
  EXPECT_EQ(Names(index.TilesAround(33.5, -115.5, 10'000.0)), (V{"n33_w116_3arc_v2.dt1", "n33w116_1deg_from_srtm3.dem"}));
  EXPECT_EQ(Names(index.TilesAround(42.93, -122.19, 5'000.0)), (V{"crater_0513.bt"}));  // VTP BT
  EXPECT_THROW(index.TilesAround(0.0, 0.0, 10'000.0), InvalidArgument);             // nothing there
}

}  // namespace
}  // namespace horizonreg
