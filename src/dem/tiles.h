// SPDX-License-Identifier: MIT
// DEMs as users have them: a folder of tiles (SRTM/HGT names, GeoTIFFs,
// DTED, a VRT, ...). The tiles around a position are found by their extents.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "dem/terrain.h"

namespace horizonreg {

class DemTileIndex {
 public:
  // Scans `dir` and its subfolders for DEM files (.hgt .tif .tiff .dt0 .dt1
  // .dt2 .dem .bt .vrt .img .npz, case-insensitive) and reads each one's
  // WGS84 extent: from the name for SRTM tiles (N47E009.hgt covers 47-48 N,
  // 9-10 E), else from the file's georeference. Files that a VRT in the
  // folder is made of are left to the VRT. Throws IoError when `dir` is not a
  // folder or holds no DEM file, naming it; a file GDAL cannot open is an
  // IoError naming the file.
  explicit DemTileIndex(const std::string& dir);

  // The files whose extent comes within `radius_m` of (lat, lon), ordered by
  // name. Throws InvalidArgument naming the folder when none contains
  // (lat, lon) itself.
  std::vector<std::string> TilesAround(double lat_deg, double lon_deg, double radius_m) const;

  const std::vector<std::pair<std::string, GeoBox>>& tiles() const { return tiles_; }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
  std::vector<std::pair<std::string, GeoBox>> tiles_;
};

// The DEM files to open for a position: `dem` as given, or the tiles of
// `dem_dir` within `radius_m` of (lat, lon). Throws InvalidArgument when
// both or neither are given.
std::vector<std::string> DemFilesFor(const std::vector<std::string>& dem, const std::string& dem_dir, double lat_deg,
                                     double lon_deg, double radius_m);

// The extent of an SRTM-named tile ("N47E009.hgt", "s12w077.hgt"), posts
// included (1 deg square); false when the name is not one.
bool HgtNameExtent(const std::string& file_name, GeoBox& box);

}  // namespace horizonreg
