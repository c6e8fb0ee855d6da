// SPDX-License-Identifier: MIT
// The cone ring's far cones (5-8 km around (46, 8)) with near hills 0.6-1.5 km
// in front of them, north-east of the observer: a synthetic site whose view
// carries the observer's position (position and locate tests); and the exact
// skyline of a pose there (header-only: the tests using it link hr_horizon
// and hr_match).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/predicted.h"
#include "skyline/skyline.h"
#include "testing/synthetic_dem.h"
#include "util/angles.h"

namespace horizonreg::testing {

constexpr double kNearFarLat = 46.0, kNearFarLon = 8.0;

inline TerrainWindow NearFarWindow() {
  constexpr double kLat = kNearFarLat, kLon = kNearFarLon;
  std::vector<std::function<double(double, double)>> hills;
  const double m_lat = 1.0 / 111'200.0, m_lon = m_lat / std::cos(DegToRad(kLat));
  for (int i = 0; i < 9; ++i) {
    const double a = DegToRad(i * 37.0 + 5.0), d = 0.06 + 0.015 * (i % 3);
    hills.push_back(ConeHeight(kLat + d * std::cos(a), kLon + d * std::sin(a) / std::cos(DegToRad(kLat)), 500.0,
                               700.0 + 180.0 * (i % 4), 2500.0 + 400.0 * (i % 2)));
  }
  const struct {
    double az_deg, dist_m, height_m, radius_m;
  } near[] = {{15, 700, 90, 350}, {40, 1100, 140, 450}, {62, 850, 70, 300}, {80, 1500, 160, 500}};
  for (const auto& h : near) {
    const double a = DegToRad(h.az_deg);
    hills.push_back(ConeHeight(kLat + h.dist_m * std::cos(a) * m_lat, kLon + h.dist_m * std::sin(a) * m_lon, 500.0,
                               500.0 + h.height_m, h.radius_m));
  }
  DemGrid g = SynthesizeDem(46.12, 7.84, 1.0 / 2400, 770, 577, [&](double lat, double lon) {
    double z = 500.0;
    for (const auto& f : hills) z = std::max(z, f(lat, lon));
    return z;
  });
  return WindowOf(std::move(g));
}

// The exact skyline of `pose` seen from `eye` (the DEM horizon at 0.1 deg
// projected), every column confident.
inline Skyline ExactSkyline(const TerrainWindow& w, const GeodeticPoint& eye, const CameraPose& pose,
                            const CameraIntrinsics& k, double max_distance_m) {
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  ho.max_distance_m = max_distance_m;
  const HorizonProfile h = ComputeHorizon(w, eye, ho);
  Skyline s;
  s.width = k.width, s.height = k.height;
  s.y = PredictedSkyline(h, pose, k);
  s.confidence.assign(k.width, 1.0);
  return s;
}

}  // namespace horizonreg::testing
