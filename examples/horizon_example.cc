// SPDX-License-Identifier: MIT
// Step 1 of the examples ladder: the 360-degree horizon of a DEM.
//
//   horizon_example DEM_FILE LAT LON
//
// Opens the DEM (any GDAL raster), reads the posts within 100 km, puts the
// eye 1.7 m above the terrain and prints the highest point of the horizon.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "dem/terrain.h"
#include "horizon/horizon.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s DEM_FILE LAT LON\n", argv[0]);
    return 2;
  }
  try {
    using namespace horizonreg;
    const double lat = std::atof(argv[2]), lon = std::atof(argv[3]);
    HorizonOptions options;  // 0.25-deg bins, 100 km, refraction k = 0.13
    const Terrain terrain({argv[1]});
    const TerrainWindow window = terrain.ReadWindow({lat, lon, 0.0}, options.max_distance_m);
    const GeodeticPoint eye = ResolveObserver(window, lat, lon, /*agl_m=*/1.7, /*alt_m=*/std::nullopt);
    const HorizonProfile horizon = ComputeHorizon(window, eye, options);
    int top = 0;
    for (int i = 0; i < horizon.size(); ++i)
      if (horizon.elevation_deg[i] > horizon.elevation_deg[top]) top = i;
    std::printf("eye %.1f m; highest horizon point: azimuth %.2f deg, elevation %.3f deg, %.1f km away at %.5f, %.5f\n",
                eye.height_m, horizon.AzimuthDeg(top), horizon.elevation_deg[top], horizon.distance_m[top] / 1000.0,
                horizon.lat_deg[top], horizon.lon_deg[top]);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
