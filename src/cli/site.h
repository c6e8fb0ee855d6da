// SPDX-License-Identifier: MIT
// The observer's site: terrain window and eye position, shared by the
// commands that need a DEM (horizon, register, overlay, render, demo).
#pragma once

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
