// SPDX-License-Identifier: MIT
// Terrain: one or several elevation rasters opened through GDAL, read as
// in-memory windows around an observer.
//
// Formats: everything GDAL reads (SRTM HGT 1" and 3", DTED, USGS DEM ASCII
// 7.5-minute and 1-degree, GeoTIFF, VRT, VTP BT, ...), in a geographic or a
// projected CRS, plus matplotlib's sample-data layout `.npz` (arrays
// elevation, xmin, xmax, ymin, ymax with ymin the northern edge and row 0 the
// northern row; see dem/npz_dem.h).
//
// Mosaics: files on the same geographic lattice (e.g. adjacent SRTM tiles,
// which share their edge posts) are merged into one grid, so the surface is
// continuous across tile edges and a ridge on the next tile is not lost
// (paper, Fig. 7). Files on other lattices or in projected CRSs become grids
// of their own; the horizon takes the maximum over grids.
//
// Voids (nodata, SRTM holes) are filled by GDALFillNodata (inverse-distance
// interpolation, up to kMaxVoidFillPx posts from valid data) within the area a
// file covers; posts outside every file stay NaN.
//
// Surface: the bilinear interpolation of the posts (dem/dem_grid.h).
// Thread safety: a Terrain must not be used from two threads at once (GDAL
// dataset handles are not thread-safe). The DemGrids it returns are plain
// values, safe to share read-only.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dem/dem_grid.h"
#include "geo/geodesy.h"

namespace horizonreg {

inline constexpr double kMaxVoidFillPx = 200.0;
// The memory a window may take by default (heights, positions of projected
// grids, void-filling scratch): 2 GiB, e.g. a 100 km radius over 1" SRTM
// (about 180 million posts) fits, a 20 GB VRT read whole does not.
inline constexpr size_t kDefaultMaxWindowBytes = size_t{2} << 30;

// The posts of all grids within a distance of a centre point.
struct TerrainWindow {
  std::vector<DemGrid> grids;
  // Bilinear height at a position, from the first grid that has data there.
  std::optional<double> HeightAt(double lat_deg, double lon_deg) const;
};

// A copy of `window` whose projected (non-separable) grids carry their
// posts' sines and cosines (DemGrid::IndexTrig), for many horizons over one
// window (the position check's wide look, locate's viewpoints); nullopt
// when it has no projected grid without them, or more than `max_posts`
// posts (about 50 bytes a post while the copy lives). On the real photos'
// 100 m projected DEM (377 000 posts) the copy and its trigonometry take
// about 15 ms, a horizon of the position check's places about 0.5 ms less.
inline constexpr size_t kMaxTrigIndexedPosts = size_t{2} << 20;
std::optional<TerrainWindow> WithPostTrig(const TerrainWindow& window, size_t max_posts = kMaxTrigIndexedPosts);

// A WGS84 bounding box, degrees (east may exceed 180 for a box across the antimeridian).
struct GeoBox {
  double south = 0.0, north = 0.0, west = 0.0, east = 0.0;
};

class Terrain {
 public:
  // Opens every file (metadata only; heights are read by ReadWindow).
  // Throws IoError naming the file when it is missing, unreadable, not a
  // raster or has no usable georeference; InvalidArgument if `paths` is empty.
  explicit Terrain(const std::vector<std::string>& paths);
  ~Terrain();
  Terrain(Terrain&&) noexcept;
  Terrain& operator=(Terrain&&) noexcept;

  // Reads the posts within `radius_m` of `center` (plus one post of margin),
  // mosaics and fills voids. Throws InvalidArgument when no file covers the
  // centre position (observer outside every DEM) or the window holds no data
  // (all voids); IoError on read failures.
  // A window whose grids would take more than max_window_bytes() is an
  // InvalidArgument saying how many posts and bytes it needs, before any is
  // read.
  TerrainWindow ReadWindow(const GeodeticPoint& center, double radius_m) const;
  void set_max_window_bytes(size_t bytes) { max_window_bytes_ = bytes; }
  size_t max_window_bytes() const { return max_window_bytes_; }

  // True if some file's extent contains the position (its data may be void).
  bool Covers(double lat_deg, double lon_deg) const;
  // WGS84 position of the centre post of file i (0 <= i < paths().size()).
  GeodeticPoint CenterOf(size_t i) const;
  const std::vector<std::string>& paths() const;
  // WGS84 bounding box of file i's posts (corners and edge points transformed).
  GeoBox ExtentOf(size_t i) const;
  // The files a dataset is made of beside file i itself (a VRT's sources), as GDAL lists them.
  std::vector<std::string> SourceFilesOf(size_t i) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  size_t max_window_bytes_ = kDefaultMaxWindowBytes;
};

// Sea-level fill: adds a grid of 0 m heights covering `radius_m` around
// `center` (last, so every file's data wins in HeightAt and the horizon takes
// the maximum over grids): the sea where no file has data, e.g. the missing
// SRTM tiles off a coast. Land below sea level would read as sea.
void AddSeaLevel(TerrainWindow& window, const GeodeticPoint& center, double radius_m);

// GDAL's drivers registered (once per process) and its errors silenced.
// OpenCV's image decoding registers them too, on its first call (its GDAL
// decoder), and two registrations at once crash (seen: GDALRegister_WMS,
// a DEM opened on one thread while another decoded its first photo). So
// whatever decodes images calls this first: OpenCV's registration then
// always finds the drivers in place.
void EnsureGdalRegistered();

}  // namespace horizonreg
