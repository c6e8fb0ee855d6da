// SPDX-License-Identifier: MIT
// A camera position and what every photo taken there shares: the DEM window
// around it, the observer's eye and the 360-degree horizon at the
// registration step, built once and reused by every photo (a camera network's
// station, a video, a batch).
#pragma once

#include <algorithm>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "dem/terrain.h"
#include "geo/geodesy.h"
#include "horizon/horizon.h"
#include "overlay/landmarks.h"
#include "util/thread_pool.h"

namespace horizonreg {

// The registration horizon's azimuth step: each 0.1-deg bin holds its
// maximum, coarser bins bias pitch.
constexpr double kRegistrationStepDeg = 0.1;

struct SiteOptions {
  std::optional<double> agl_m;  // eye height above the ground (default kDefaultEyeHeightM)
  std::optional<double> alt_m;  // or the eye's altitude above the ellipsoid (not both)
  double max_distance_m = 100'000.0;
  double azimuth_step_deg = kRegistrationStepDeg;
  double refraction = kDefaultRefraction;
  bool sea_level_fill = false;  // the sea at 0 m where no DEM file has data (AddSeaLevel)
  size_t max_dem_bytes = kDefaultMaxWindowBytes;  // the DEM window's memory bound (Terrain::ReadWindow)
  HorizonOptions horizon_options() const;  // the step, refraction and distance above
  void Check() const;  // Throws InvalidArgument naming the field.
};

class Site {
 public:
  // Opens the DEM file(s) (a mosaic when several), reads the window within
  // max_distance_m of (lat, lon), resolves the eye and computes the horizon
  // (on `pool` when given). Throws InvalidArgument / IoError naming the file
  // or value.
  Site(const std::vector<std::string>& dem, double lat, double lon, const SiteOptions& options,
       ThreadPool* pool = nullptr);
  // From a window already read (tests, several sites in one DEM window).
  Site(TerrainWindow window, double lat, double lon, const SiteOptions& options, ThreadPool* pool = nullptr);
  Site(const Site&) = delete;
  Site& operator=(const Site&) = delete;

  const TerrainWindow& window() const { return window_; }
  const GeodeticPoint& observer() const { return observer_; }
  const HorizonProfile& horizon() const { return horizon_; }
  const SiteOptions& options() const { return options_; }
  HorizonOptions horizon_options() const;
  // Inner ridge lines at the horizon's step (the overlay's), computed on
  // first use; thread-safe.
  const std::vector<std::vector<Ridge>>& ridges() const;
  // Eye height above the terrain under the observer, metres (at least 0.1):
  // the overlay's ground-plane grid lies that far below the eye.
  double EyeAboveGroundM() const;
  // Milliseconds spent opening the DEM and reading the window, and computing the horizon.
  double load_ms() const { return load_ms_; }
  double horizon_ms() const { return horizon_ms_; }

 private:
  void Build(double lat, double lon, ThreadPool* pool);
  SiteOptions options_;
  TerrainWindow window_;
  GeodeticPoint observer_;
  HorizonProfile horizon_;
  double load_ms_ = 0.0, horizon_ms_ = 0.0;
  mutable std::once_flag ridges_once_;
  mutable std::vector<std::vector<Ridge>> ridges_;
};

// Landmarks for the overlay: from the file when given (snapped and checked
// for visibility), else the prominent summits of the horizon.
std::vector<ResolvedLandmark> OverlayLandmarks(const Site& site, const std::string& landmarks_path);

}  // namespace horizonreg
