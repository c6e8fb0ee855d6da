// SPDX-License-Identifier: MIT
// DEM files through dem Terrain: opening (GDAL drivers, the .npz reader),
// extent and centre, and reading a window (mosaic, void filling) around the
// file's centre. The first input byte picks the file name, and so the
// driver: SRTM HGT (plain and zipped: the driver needs the tile name and a
// full 1201 x 1201 tile, which zips to a few KB), DTED, USGS DEM, GeoTIFF,
// VTP BT, VRT, matplotlib .npz.
#include <cmath>
#include <cstdlib>

#include "dem/terrain.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  if (size < 1) return 0;
  static const char* const kNames[] = {"N46E007.hgt", "N46E007.hgt.zip", "dem.dt1", "dem.dem",
                                       "dem.tif",     "dem.bt",          "dem.vrt", "dem.npz"};
  const std::string path = fuzz::WriteScratch(kNames[data[0] & 7], data + 1, size - 1);
  fuzz::ExpectingBadInput([&] {
    Terrain terrain({path});
    terrain.set_max_window_bytes(size_t{64} << 20);  // the library's own bound, small enough for the fuzzer
    (void)terrain.ExtentOf(0);
    (void)terrain.SourceFilesOf(0);
    const GeodeticPoint center = terrain.CenterOf(0);
    if (!terrain.Covers(center.lat_deg, center.lon_deg)) return;
    const TerrainWindow window = terrain.ReadWindow(center, 3000.0);
    (void)window.HeightAt(center.lat_deg, center.lon_deg);
  });
  return 0;
}
