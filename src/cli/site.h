// SPDX-License-Identifier: MIT
// The observer's site: terrain window and eye position, shared by the
// commands that need a DEM (horizon, register, overlay, render, demo).
#pragma once

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "dem/terrain.h"
#include "geo/geodesy.h"
#include "horizon/horizon.h"
#include "overlay/landmarks.h"

namespace horizonreg::cli {

struct Site {
  TerrainWindow window;
  GeodeticPoint observer;
  // Eye height above the terrain under the observer, metres (at least 0.1):
  // the overlay's ground-plane grid lies that far below the eye.
  double EyeAboveGroundM() const {
    return std::max(0.1, observer.height_m - window.HeightAt(observer.lat_deg, observer.lon_deg).value_or(0.0));
  }
};

// Opens the DEM(s), reads the window within max_distance_m and resolves the
// eye position (--agl or --alt, default 1.7 m above the ground).
Site LoadSite(const std::vector<std::string>& dem, double lat, double lon, std::optional<double> agl,
              std::optional<double> alt, double max_distance_m);

// Landmarks for the overlay: from the file when given (snapped and checked
// for visibility), else the prominent summits of the horizon.
std::vector<ResolvedLandmark> OverlayLandmarks(const Site& site, const HorizonProfile& horizon,
                                               const std::string& landmarks_path, double refraction);

}  // namespace horizonreg::cli
