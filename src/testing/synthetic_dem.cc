// SPDX-License-Identifier: MIT
#include "testing/synthetic_dem.h"

#include <algorithm>
#include <cmath>

#include "geo/geodesy.h"

namespace horizonreg::testing {

DemGrid SynthesizeDem(double north_deg, double west_deg, double spacing_deg, int width, int height,
                      const std::function<double(double, double)>& height_fn) {
  DemGrid g;
  g.width = width;
  g.height = height;
  g.separable = true;
  g.lat0_deg = north_deg;
  g.dlat_deg = -spacing_deg;
  g.lon0_deg = west_deg;
  g.dlon_deg = spacing_deg;
  g.source = "synthetic";
  g.height_m.resize(static_cast<size_t>(width) * height);
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c)
      g.height_m[static_cast<size_t>(r) * width + c] = static_cast<float>(height_fn(g.LatAt(c, r), g.LonAt(c, r)));
  return g;
}

std::function<double(double, double)> ConeHeight(double lat_deg, double lon_deg, double base_m, double peak_m,
                                                 double radius_m) {
  return [=](double lat, double lon) {
    const LocalFrame frame({lat_deg, lon_deg, 0.0});
    const Eigen::Vector3d enu = frame.EnuFromGeodetic({lat, lon, 0.0});
    const double r = std::hypot(enu.x(), enu.y());
    return base_m + std::max(0.0, peak_m * (1.0 - r / radius_m));
  };
}

}  // namespace horizonreg::testing
