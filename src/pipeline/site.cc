// SPDX-License-Identifier: MIT
#include "pipeline/site.h"

#include <chrono>
#include <cmath>

#include "util/errors.h"

namespace horizonreg {

namespace {
double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
void CheckPosition(double lat, double lon) {
  if (!(std::abs(lat) <= 90.0)) ThrowField("latitude", lat, "within [-90, 90]");
  if (!(std::abs(lon) <= 360.0)) ThrowField("longitude", lon, "within [-180, 360]");
}
}  // namespace

void SiteOptions::Check() const {
  if (agl_m && alt_m) throw InvalidArgument("SiteOptions: give the eye height above ground or its altitude, not both");
  if (agl_m && !(std::isfinite(*agl_m) && *agl_m >= 0.0 && *agl_m < 20'000.0))
    ThrowField("SiteOptions::agl_m", *agl_m, "in [0, 20000) metres");
  if (alt_m && !(std::isfinite(*alt_m) && std::abs(*alt_m) < 20'000.0))
    ThrowField("SiteOptions::alt_m", *alt_m, "within +-20000 metres");
  if (!(max_distance_m > 0.0 && max_distance_m <= 1'000'000.0))
    ThrowField("SiteOptions::max_distance_m", max_distance_m, "in (0, 1000000] metres");
  horizon_options().Check();
}

HorizonOptions SiteOptions::horizon_options() const {
  HorizonOptions ho;
  ho.azimuth_step_deg = azimuth_step_deg;
  ho.refraction = refraction;
  ho.max_distance_m = max_distance_m;
  return ho;
}

HorizonOptions Site::horizon_options() const { return options_.horizon_options(); }

Site::Site(const std::vector<std::string>& dem, double lat, double lon, const SiteOptions& options, ThreadPool* pool)
    : options_(options) {
  options_.Check();
  CheckPosition(lat, lon);
  const auto t0 = std::chrono::steady_clock::now();
  Terrain terrain(dem);
  terrain.set_max_window_bytes(options_.max_dem_bytes);
  window_ = terrain.ReadWindow({lat, lon, 0.0}, options_.max_distance_m);
  if (options_.sea_level_fill) AddSeaLevel(window_, {lat, lon, 0.0}, options_.max_distance_m);
  load_ms_ = MsSince(t0);
  Build(lat, lon, pool);
}

Site::Site(TerrainWindow window, double lat, double lon, const SiteOptions& options, ThreadPool* pool)
    : options_(options), window_(std::move(window)) {
  options_.Check();
  CheckPosition(lat, lon);
  Build(lat, lon, pool);
}

void Site::Build(double lat, double lon, ThreadPool* pool) {
  observer_ = ResolveObserver(window_, lat, lon, options_.agl_m, options_.alt_m);
  const auto t0 = std::chrono::steady_clock::now();
  HorizonOptions ho = horizon_options();
  ho.pool = pool;
  horizon_ = ComputeHorizon(window_, observer_, ho);
  horizon_ms_ = MsSince(t0);
}

const std::vector<std::vector<Ridge>>& Site::ridges() const {
  std::call_once(ridges_once_, [&] { ridges_ = ComputeRidges(window_, observer_, horizon_options(), RidgeOptions{}); });
  return ridges_;
}

double Site::EyeAboveGroundM() const {
  return std::max(0.1, observer_.height_m - window_.HeightAt(observer_.lat_deg, observer_.lon_deg).value_or(0.0));
}

std::vector<ResolvedLandmark> OverlayLandmarks(const Site& site, const std::string& landmarks_path) {
  if (landmarks_path.empty()) return SummitsFromHorizon(site.horizon());
  LandmarkOptions o;
  o.refraction = site.options().refraction;
  return ResolveLandmarks(site.window(), site.observer(), LoadLandmarks(landmarks_path), o);
}

}  // namespace horizonreg
