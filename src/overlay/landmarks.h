// SPDX-License-Identifier: MIT
// Named landmarks for the overlay (DESIGN.md "Landmark files"): loading,
// snapping to the DEM summit, and whether the observer can see them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "dem/terrain.h"
#include "geo/geodesy.h"
#include "horizon/horizon.h"

namespace horizonreg {

struct Landmark {
  std::string name;
  double lat_deg = 0.0, lon_deg = 0.0;
  std::optional<double> ele_m;  // as the file gives it
};

// Reads a GeoJSON FeatureCollection of Points (properties `name`, optional
// `ele`) or a CSV `name,lat,lon[,ele]` (header optional, quoted names
// allowed). Throws IoError if unreadable, InvalidArgument naming the file and
// line/feature for malformed content or out-of-range coordinates.
std::vector<Landmark> LoadLandmarks(const std::string& path);

struct LandmarkOptions {
  double snap_radius_m = 600.0;         // Move a landmark to the highest DEM post within this distance, >= 0.
  double visibility_margin_deg = 0.05;  // Terrain on the line of sight may rise this close to the summit's angle.
  double refraction = kDefaultRefraction;
  void Check() const;
};

struct ResolvedLandmark {
  std::string name;
  double lat_deg = 0.0, lon_deg = 0.0;            // after snapping
  double height_m = 0.0;                          // DEM height at the (snapped) summit, m
  std::optional<double> ele_m;                    // the file's elevation
  double azimuth_deg = 0.0, elevation_deg = 0.0;  // as seen from the observer (refraction included)
  double distance_m = 0.0;                        // horizontal
  bool visible = false;                           // not hidden behind nearer terrain
};

// Snaps each landmark inside the terrain to its DEM summit and decides its
// visibility by marching the line of sight over the bilinear DEM surface
// (exact WGS84 positions, curvature and refraction as the horizon module).
// Landmarks outside the terrain are dropped. Thread-safe.
std::vector<ResolvedLandmark> ResolveLandmarks(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                               const std::vector<Landmark>& landmarks, const LandmarkOptions& options);

// Unnamed summits for labelling when no file is given: the peaks of the
// horizon profile that stand out by at least min_prominence_deg (name empty:
// the overlay labels them by height), at most max_count, most prominent first.
std::vector<ResolvedLandmark> SummitsFromHorizon(const HorizonProfile& horizon, double min_prominence_deg = 0.3,
                                                 int max_count = 40);

}  // namespace horizonreg
