// SPDX-License-Identifier: MIT
// Reader for the DEM layout of matplotlib's sample data (e.g. Debian's
// python-matplotlib-data jacksboro_fault_dem.npz): a NumPy .npz archive with
// `elevation` (2-D, row 0 the northern row), `xmin`, `xmax` (west and east
// longitude), `ymin` (the NORTHERN edge latitude), `ymax` (the southern) and
// `dx`, `dy` (post spacing, degrees). The extent values are post centres.
#pragma once

#include <string>
#include <vector>

namespace horizonreg {

struct NpzDem {
  int width = 0, height = 0;
  std::vector<double> elevation_m;  // row-major, row 0 north
  double west_deg = 0, east_deg = 0, north_deg = 0, south_deg = 0;
};

// Reads the archive through GDAL's /vsizip/ file system. Throws IoError
// naming the file on a missing member, an unsupported dtype or a bad header.
NpzDem ReadNpzDem(const std::string& path);

}  // namespace horizonreg
