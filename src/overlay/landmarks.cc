// SPDX-License-Identifier: MIT
#include "overlay/landmarks.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "util/angles.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg {

void LandmarkOptions::Check() const {
  if (!(snap_radius_m >= 0.0 && snap_radius_m < 50'000.0)) ThrowField("LandmarkOptions::snap_radius_m", snap_radius_m, "0 <= r < 50 km");
  if (!(visibility_margin_deg >= 0.0 && visibility_margin_deg < 10.0))
    ThrowField("LandmarkOptions::visibility_margin_deg", visibility_margin_deg, "0 <= margin < 10");
  if (!(refraction >= -1.0 && refraction <= 1.0)) ThrowField("LandmarkOptions::refraction", refraction, "-1 <= k <= 1");
}

namespace {

void CheckPosition(const std::string& path, const std::string& where, double lat, double lon) {
  if (!(std::abs(lat) <= 90.0) || !(std::abs(lon) <= 360.0)) {
    std::ostringstream m;
    m << "landmarks: '" << path << "' " << where << ": position (" << lat << ", " << lon << ") is out of range";
    throw InvalidArgument(m.str());
  }
}

}  // namespace

std::vector<Landmark> LoadLandmarks(const std::string& path) {
  const std::string text = ReadTextFile(path, "landmarks", size_t{256} << 20);
  std::vector<Landmark> out;
  const auto first = text.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
  if (first != std::string::npos && text[first] == '{') {
    const nlohmann::json j = ParseJson(text, "landmarks", path);
    if (!j.contains("features") || !j["features"].is_array())
      throw InvalidArgument("landmarks: '" + path + "' is not a GeoJSON FeatureCollection");
    int index = 0;
    for (const auto& feature : j["features"]) {
      const std::string where = "feature " + std::to_string(index++);
      const auto& g = feature.value("geometry", nlohmann::json());
      if (!g.is_object() || g.value("type", "") != "Point" || !g.contains("coordinates") ||
          !g["coordinates"].is_array() || g["coordinates"].size() < 2 || !g["coordinates"][0].is_number() ||
          !g["coordinates"][1].is_number())
        throw InvalidArgument("landmarks: '" + path + "' " + where + ": not a Point with coordinates");
      Landmark l;
      l.lon_deg = g["coordinates"][0].get<double>();
      l.lat_deg = g["coordinates"][1].get<double>();
      CheckPosition(path, where, l.lat_deg, l.lon_deg);
      const auto& p = feature.value("properties", nlohmann::json::object());
      l.name = p.contains("name") && p["name"].is_string() ? p["name"].get<std::string>() : "";
      if (p.contains("ele") && p["ele"].is_number()) l.ele_m = p["ele"].get<double>();
      if (p.contains("ele") && p["ele"].is_string()) l.ele_m = ParseDouble(p["ele"].get<std::string>());
      out.push_back(std::move(l));
    }
    return out;
  }
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  while (std::getline(lines, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const auto cells = SplitCsvLine(line);
    const std::string where = "line " + std::to_string(number);
    if (cells.size() < 3) throw InvalidArgument("landmarks: '" + path + "' " + where + ": expected name,lat,lon[,ele]");
    const auto lat = ParseDouble(cells[1]), lon = ParseDouble(cells[2]);
    if (!lat || !lon) {
      if (number == 1) continue;  // header
      throw InvalidArgument("landmarks: '" + path + "' " + where + ": lat/lon are not numbers");
    }
    CheckPosition(path, where, *lat, *lon);
    Landmark l{cells[0], *lat, *lon, std::nullopt};
    if (cells.size() > 3 && !cells[3].empty()) l.ele_m = ParseDouble(cells[3]);
    out.push_back(std::move(l));
  }
  return out;
}

std::vector<ResolvedLandmark> ResolveLandmarks(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                               const std::vector<Landmark>& landmarks, const LandmarkOptions& options) {
  options.Check();
  const LocalFrame frame(observer);
  std::vector<ResolvedLandmark> out;
  for (const Landmark& l : landmarks) {
    if (!terrain.HeightAt(l.lat_deg, l.lon_deg)) continue;
    // Snap: the highest point on a polar grid within the radius.
    const Eigen::Vector3d c = frame.EnuFromGeodetic({l.lat_deg, l.lon_deg, 0.0});
    double best_h = -INFINITY, best_lat = l.lat_deg, best_lon = l.lon_deg;
    const double r_step = 30.0;
    for (double r = 0.0; r <= options.snap_radius_m + 1e-9; r += r_step) {
      const int n = r == 0.0 ? 1 : static_cast<int>(std::ceil(2 * kPi * r / r_step));
      for (int i = 0; i < n; ++i) {
        const double a = 2 * kPi * i / n;
        const GeodeticPoint g = frame.GeodeticFromEnu({c.x() + r * std::sin(a), c.y() + r * std::cos(a), c.z()});
        const auto h = terrain.HeightAt(g.lat_deg, g.lon_deg);
        if (h && *h > best_h) best_h = *h, best_lat = g.lat_deg, best_lon = g.lon_deg;
      }
    }
    ResolvedLandmark r{l.name, best_lat, best_lon, best_h, l.ele_m};
    const Eigen::Vector3d enu = frame.EnuFromGeodetic({best_lat, best_lon, best_h});
    r.distance_m = std::hypot(enu.x(), enu.y());
    if (r.distance_m < 1.0) continue;
    const double lift = RefractionLiftM(r.distance_m, options.refraction);
    r.azimuth_deg = WrapAzimuthDeg(RadToDeg(std::atan2(enu.x(), enu.y())));
    const double tan_target = (enu.z() + lift) / r.distance_m;
    r.elevation_deg = RadToDeg(std::atan(tan_target));
    // Line of sight: terrain between must stay below the summit's angle.
    r.visible = true;
    const int samples = std::clamp(static_cast<int>(r.distance_m / 25.0), 20, 2000);
    const double margin = std::tan(DegToRad(options.visibility_margin_deg));
    for (int i = 1; i < samples; ++i) {
      const double t = static_cast<double>(i) / samples;
      const double d = t * r.distance_m;
      if (r.distance_m - d < 0.5 * options.snap_radius_m + 60.0) break;  // the summit's own flanks
      const double drop = d * d / (2.0 * kRefractionEarthRadiusM);
      const GeodeticPoint g = frame.GeodeticFromEnu({t * enu.x(), t * enu.y(), -observer.height_m - drop});
      const auto h = terrain.HeightAt(g.lat_deg, g.lon_deg);
      if (!h) continue;
      const Eigen::Vector3d p = frame.EnuFromGeodetic({g.lat_deg, g.lon_deg, *h});
      const double dd = std::hypot(p.x(), p.y());
      if (dd < 1.0) continue;
      if ((p.z() + RefractionLiftM(dd, options.refraction)) / dd > tan_target + margin) {
        r.visible = false;
        break;
      }
    }
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<ResolvedLandmark> SummitsFromHorizon(const HorizonProfile& horizon, double min_prominence_deg,
                                                 int max_count) {
  const int n = horizon.size();
  std::vector<std::pair<double, int>> peaks;  // prominence, bin
  for (int i = 0; i < n; ++i) {
    const double e = horizon.elevation_deg[i];
    if (!(e > horizon.elevation_deg[(i + n - 1) % n] && e >= horizon.elevation_deg[(i + 1) % n])) continue;
    double side_min[2] = {e, e};
    for (int s = 0; s < 2; ++s)
      for (int k = 1; k < n; ++k) {
        const double v = horizon.elevation_deg[((i + (s ? k : -k)) % n + n) % n];
        if (v > e) break;
        side_min[s] = std::min(side_min[s], v);
      }
    const double prominence = e - std::max(side_min[0], side_min[1]);
    if (prominence >= min_prominence_deg) peaks.push_back({prominence, i});
  }
  std::sort(peaks.rbegin(), peaks.rend());
  if (static_cast<int>(peaks.size()) > max_count) peaks.resize(max_count);
  std::vector<ResolvedLandmark> out;
  for (const auto& [prominence, i] : peaks) {
    ResolvedLandmark r;
    r.lat_deg = horizon.lat_deg[i];
    r.lon_deg = horizon.lon_deg[i];
    r.height_m = horizon.height_m[i];
    r.azimuth_deg = horizon.AzimuthDeg(i);
    r.elevation_deg = horizon.elevation_deg[i];
    r.distance_m = horizon.distance_m[i];
    r.visible = true;
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace horizonreg
