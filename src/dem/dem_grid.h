// SPDX-License-Identifier: MIT
// DemGrid: one window of elevation posts in memory, with the geographic
// position of every post.
//
// Terrain surface model: between DEM posts (pixel centres) the terrain is the
// bilinear interpolation of the four surrounding posts. Every horizonreg
// computation (horizon, ridge lines, heights) uses this surface.
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace horizonreg {

struct DemGrid {
  int width = 0;   // posts per row
  int height = 0;  // rows
  // Heights in metres, row-major, voids filled by interpolation; NaN where
  // the grid has no data (outside every source file, or a void too large to
  // fill).
  std::vector<float> height_m;
  // Georeference. When `separable`, the post in column c, row r lies at
  // latitude lat0_deg + r * dlat_deg and longitude lon0_deg + c * dlon_deg
  // (WGS84). Otherwise lat_deg / lon_deg hold every post's position
  // (row-major), e.g. for a UTM grid.
  bool separable = true;
  double lat0_deg = 0.0, dlat_deg = 0.0, lon0_deg = 0.0, dlon_deg = 0.0;
  std::vector<double> lat_deg, lon_deg;
  std::string source;  // file name(s), for messages
  // Non-separable grids: an affine guess of (col, row) from (lon, lat), set
  // by IndexPositions() and refined by Newton iterations in PixelOf.
  double col_from_lonlat[3] = {0, 0, 0}, row_from_lonlat[3] = {0, 0, 0};
  void IndexPositions();
  // Non-separable grids: sin and cos of each post's latitude and longitude
  // (4 per post, row-major; 32 bytes a post), set by IndexTrig(): a horizon
  // sweep then takes the sines and cosines of (longitude - observer's
  // longitude) from them by the difference formulae, instead of two sincos
  // per post and place. Worth it for many places over one grid (the
  // position check's wide look: 144); empty otherwise (building it costs
  // about a horizon). Cleared by IndexPositions().
  std::vector<double> post_trig;
  void IndexTrig();
  // Horizon sweeps go over blocks of kBlock rows by kBlock columns, split
  // into quarters down to kBlock / 4. The highest post of each block of size
  // S in {kBlock, kBlock / 2, kBlock / 4} at (rb, cb), over rows
  // [rb * S - 1, (rb + 1) * S) and columns [cb * S, (cb + 1) * S] (the row
  // above it and the next block's first column, clipped to the grid; -inf
  // when all void), lets a sweep skip blocks that cannot reach the horizon.
  // Filled by IndexBlocks() (Terrain does it; the sweep scans when empty).
  static constexpr int kBlock = 32;
  std::vector<float> block_max[3];  // level l: blocks of kBlock >> l
  // The indexed maximum of rows [r0, r1) (and the row above) and columns
  // [c0, c1] when that is one whole indexed block, else nullptr.
  const float* BlockMax(int r0, int r1, int c0, int c1) const {
    for (int l = 0; l < 3; ++l) {
      const int size = kBlock >> l;
      if (block_max[l].empty() || r0 % size || c0 % size || r1 != std::min(height, r0 + size) ||
          c1 != std::min(width - 1, c0 + size))
        continue;
      const int cols = (width - 1 + size - 1) / size;
      return &block_max[l][static_cast<size_t>(r0 / size) * cols + c0 / size];
    }
    return nullptr;
  }
  void IndexBlocks();

  float At(int col, int row) const { return height_m[static_cast<size_t>(row) * width + col]; }
  double LatAt(int col, int row) const {
    return separable ? lat0_deg + row * dlat_deg : lat_deg[static_cast<size_t>(row) * width + col];
  }
  double LonAt(int col, int row) const {
    return separable ? lon0_deg + col * dlon_deg : lon_deg[static_cast<size_t>(row) * width + col];
  }
  // Fractional (col, row) of a WGS84 position; nullopt when outside the grid's
  // posts. Exact for separable grids; for the others, found by inverting the
  // local bilinear map of positions (Newton iterations, < 1e-6 px).
  std::optional<std::pair<double, double>> PixelOf(double query_lat_deg, double query_lon_deg) const;
  // Bilinear terrain height at a WGS84 position; nullopt outside the grid or
  // where a surrounding post has no data.
  std::optional<double> HeightAt(double query_lat_deg, double query_lon_deg) const;
  // The same at a fractional post (col, row), as PixelOf gives it.
  std::optional<double> HeightAtPixel(double col, double row) const;
  // Post spacing in metres along a row and along a column, near the centre.
  double SpacingM() const;
};

}  // namespace horizonreg
