// SPDX-License-Identifier: MIT
// Synthetic DEMs for tests: a WGS84 lat/lon grid whose heights come from a
// function of (lat, lon). Pure values, no files.
#pragma once

#include <functional>

#include "dem/terrain.h"

namespace horizonreg::testing {

// A separable grid of width x height posts, post (0, 0) at the north-west
// corner (north_deg, west_deg), spacing spacing_deg in both directions.
DemGrid SynthesizeDem(double north_deg, double west_deg, double spacing_deg, int width, int height,
                      const std::function<double(double lat_deg, double lon_deg)>& height_fn);

// A cone of height peak_m (base radius radius_m, on a plane at base_m) centred at (lat, lon).
std::function<double(double, double)> ConeHeight(double lat_deg, double lon_deg, double base_m, double peak_m,
                                                 double radius_m);

inline TerrainWindow WindowOf(DemGrid grid) {
  TerrainWindow w;
  w.grids.push_back(std::move(grid));
  return w;
}

}  // namespace horizonreg::testing
