// SPDX-License-Identifier: MIT
// A ring of nine cones 5-8 km around an observer at (46, 8), and its horizon
// (0.1 deg bins, 30 km): a small synthetic site for tracking and
// registration tests (header-only: the tests using it link hr_horizon).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

#include "horizon/horizon.h"
#include "testing/synthetic_dem.h"
#include "util/angles.h"

namespace horizonreg::testing {

struct ConeRing {
  TerrainWindow window;
  GeodeticPoint eye;
  HorizonProfile horizon;
};

inline ConeRing MakeConeRing() {
  std::vector<std::function<double(double, double)>> cones;
  const double lat0 = 46.0, lon0 = 8.0;
  for (int i = 0; i < 9; ++i) {
    const double a = DegToRad(i * 37.0 + 5.0), d = 0.06 + 0.015 * (i % 3);
    cones.push_back(ConeHeight(lat0 + d * std::cos(a), lon0 + d * std::sin(a) / std::cos(DegToRad(lat0)), 500.0,
                               700.0 + 180.0 * (i % 4), 2500.0 + 400.0 * (i % 2)));
  }
  DemGrid g = SynthesizeDem(46.15, 7.8, 1.0 / 1200, 500, 361, [&](double lat, double lon) {
    double h = 500.0;
    for (const auto& f : cones) h = std::max(h, f(lat, lon));
    return h;
  });
  ConeRing ring;
  ring.window = WindowOf(std::move(g));
  ring.eye = ResolveObserver(ring.window, lat0, lon0, 1.7, std::nullopt);
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  ho.max_distance_m = 30'000.0;
  ring.horizon = ComputeHorizon(ring.window, ring.eye, ho);
  return ring;
}

}  // namespace horizonreg::testing
