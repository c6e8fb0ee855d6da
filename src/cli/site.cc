// SPDX-License-Identifier: MIT
#include "cli/site.h"

#include <cmath>

#include "util/errors.h"

namespace horizonreg::cli {

Site LoadSite(const std::vector<std::string>& dem, double lat, double lon, std::optional<double> agl,
              std::optional<double> alt, double max_distance_m) {
  if (!(std::abs(lat) <= 90.0)) throw InvalidArgument("--lat must be within [-90, 90]");
  if (!(std::abs(lon) <= 360.0)) throw InvalidArgument("--lon must be within [-180, 360]");
  const Terrain terrain(dem);
  Site s{terrain.ReadWindow({lat, lon, 0.0}, max_distance_m), {}};
  s.observer = ResolveObserver(s.window, lat, lon, agl, alt);
  return s;
}

std::vector<ResolvedLandmark> OverlayLandmarks(const Site& site, const HorizonProfile& horizon,
                                               const std::string& landmarks_path, double refraction) {
  if (landmarks_path.empty()) return SummitsFromHorizon(horizon);
  LandmarkOptions o;
  o.refraction = refraction;
  return ResolveLandmarks(site.window, site.observer, LoadLandmarks(landmarks_path), o);
}

}  // namespace horizonreg::cli
