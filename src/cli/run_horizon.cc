// SPDX-License-Identifier: MIT
#include <CLI/CLI.hpp>
#include <chrono>
#include <iostream>
#include <sstream>

#include "cli/commands.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "dem/tiles.h"
#include "overlay/horizon_plot.h"
#include "util/errors.h"

namespace horizonreg::cli {

using nlohmann::json;

void AddHorizonCommand(CLI::App& app, HorizonArgs& a) {
  CLI::App* c = app.add_subcommand("horizon", "Compute the 360-degree terrain horizon from DEM file(s)");
  c->add_option("--dem", a.dem, "DEM file (any GDAL raster, or a matplotlib .npz); repeat for a mosaic");
  c->add_option("--dem-dir", a.dem_dir, "Folder of DEM tiles: those around the observer are found by their extents");
  c->add_flag("--sea-level-fill", a.sea_level_fill, "Ground missing from every DEM file is the sea at 0 m");
  c->add_option("--lat", a.lat, "Observer latitude, degrees (WGS84)")->required();
  c->add_option("--lon", a.lon, "Observer longitude, degrees (WGS84)")->required();
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the terrain, m (default 1.7)");
  auto* alt = c->add_option("--alt", a.alt, "Absolute eye altitude, m (as the DEM's heights)");
  agl->excludes(alt);
  c->add_option("--step", a.options.azimuth_step_deg, "Azimuth bin width and spacing, degrees; divides 360")
      ->capture_default_str();
  c->add_option("--max-distance", a.options.max_distance_m, "Ignore terrain farther than this, m")
      ->capture_default_str();
  c->add_option("--refraction", a.options.refraction, "Refraction coefficient k (0 = pure geometry)")
      ->capture_default_str();
  c->add_option("--threads", a.options.num_threads, "Threads")->capture_default_str();
  c->add_option("--format", a.format, "Output format")
      ->check(CLI::IsMember({"json", "csv", "geojson"}))
      ->capture_default_str();
  c->add_option("-o,--output", a.output, "Output file ('-' = stdout)")->capture_default_str();
  c->add_option("--plot", a.plot, "Also draw a panorama chart to this PNG");
  c->add_flag("--ridges", a.ridges, "Also compute the inner ridge lines (JSON output and plot)");
}

std::string HorizonToJson(const HorizonProfile& p, const std::vector<std::vector<Ridge>>& ridges) {
  json j;
  j["observer"] = {{"lat", Rounded(p.observer.lat_deg, 8)},
                   {"lon", Rounded(p.observer.lon_deg, 8)},
                   {"eye_height_m", Rounded(p.observer.height_m, 2)},
                   {"ground_height_m", Rounded(p.ground_height_m, 2)}};
  j["step_deg"] = p.azimuth_step_deg;
  j["refraction"] = p.refraction;
  json az = json::array(), el = json::array(), d = json::array(), lat = json::array(), lon = json::array(),
       h = json::array();
  for (int i = 0; i < p.size(); ++i) {
    az.push_back(Rounded(p.AzimuthDeg(i), 6));
    el.push_back(Rounded(p.elevation_deg[i], 5));
    d.push_back(Rounded(p.distance_m[i], 1));
    lat.push_back(Rounded(p.lat_deg[i], 7));
    lon.push_back(Rounded(p.lon_deg[i], 7));
    h.push_back(Rounded(p.height_m[i], 1));
  }
  j["azimuth_deg"] = std::move(az);
  j["elevation_deg"] = std::move(el);
  j["distance_m"] = std::move(d);
  j["lat"] = std::move(lat);
  j["lon"] = std::move(lon);
  j["height_m"] = std::move(h);
  if (!ridges.empty()) {
    json r = json::array();
    for (const auto& bin : ridges) {
      json b = json::array();
      for (const Ridge& x : bin) b.push_back({Rounded(x.elevation_deg, 5), Rounded(x.distance_m, 1)});
      r.push_back(std::move(b));
    }
    j["ridges"] = std::move(r);  // per bin: [[elevation_deg, distance_m], ...], highest first
  }
  return j.dump() + "\n";
}

std::string HorizonToCsv(const HorizonProfile& p) {
  std::ostringstream s;
  s.precision(10);
  s << "azimuth_deg,elevation_deg,distance_m,lat,lon,height_m\n";
  auto v = [](double x) { return std::isfinite(x) ? std::to_string(x) : std::string(); };
  for (int i = 0; i < p.size(); ++i) {
    s << p.AzimuthDeg(i) << "," << v(p.elevation_deg[i]) << "," << v(p.distance_m[i]) << "," << v(p.lat_deg[i]) << ","
      << v(p.lon_deg[i]) << "," << v(p.height_m[i]) << "\n";
  }
  return s.str();
}

std::string HorizonToGeoJson(const HorizonProfile& p) {
  // The horizon as a 3D LineString (lon, lat, height) through the horizon
  // points in azimuth order, closed over north; split where bins are empty.
  json lines = json::array();
  json cur = json::array();
  const int n = p.size();
  for (int k = 0; k <= n; ++k) {
    const int i = k % n;
    if (!std::isfinite(p.elevation_deg[i])) {
      if (cur.size() > 1) lines.push_back(cur);
      cur = json::array();
      continue;
    }
    cur.push_back({Rounded(p.lon_deg[i], 7), Rounded(p.lat_deg[i], 7), Rounded(p.height_m[i], 1)});
  }
  if (cur.size() > 1) lines.push_back(cur);
  json geometry = lines.size() == 1 ? json{{"type", "LineString"}, {"coordinates", lines[0]}}
                                    : json{{"type", "MultiLineString"}, {"coordinates", lines}};
  json fc = {
      {"type", "FeatureCollection"},
      {"features",
       {{{"type", "Feature"},
         {"properties", {{"name", "horizon"}, {"step_deg", p.azimuth_step_deg}, {"refraction", p.refraction}}},
         {"geometry", geometry}},
        {{"type", "Feature"},
         {"properties", {{"name", "observer"}, {"eye_height_m", Rounded(p.observer.height_m, 2)}}},
         {"geometry",
          {{"type", "Point"},
           {"coordinates",
            {Rounded(p.observer.lon_deg, 8), Rounded(p.observer.lat_deg, 8), Rounded(p.observer.height_m, 2)}}}}}}}};
  return fc.dump() + "\n";
}

int RunHorizon(const HorizonArgs& a) {
  // Check everything before any work (STYLE.md section 6).
  a.options.Check();
  if (!std::isfinite(a.lat) || a.lat < -90 || a.lat > 90) {
    std::ostringstream m;
    m << "--lat " << a.lat << " is not a latitude in [-90, 90]";
    throw InvalidArgument(m.str());
  }
  if (!std::isfinite(a.lon) || a.lon < -180 || a.lon > 360) {
    std::ostringstream m;
    m << "--lon " << a.lon << " is not a longitude in [-180, 360]";
    throw InvalidArgument(m.str());
  }
  const Terrain terrain(DemFilesFor(a.dem, a.dem_dir, a.lat, a.lon, a.options.max_distance_m));
  TerrainWindow window = terrain.ReadWindow({a.lat, a.lon, 0.0}, a.options.max_distance_m);
  if (a.sea_level_fill) AddSeaLevel(window, {a.lat, a.lon, 0.0}, a.options.max_distance_m);
  const GeodeticPoint observer = ResolveObserver(window, a.lat, a.lon, a.agl, a.alt);
  const HorizonProfile profile = ComputeHorizon(window, observer, a.options);
  std::vector<std::vector<Ridge>> ridges;
  if (a.ridges) ridges = ComputeRidges(window, observer, a.options, RidgeOptions{});
  std::string text;
  if (a.format == "json")
    text = HorizonToJson(profile, ridges);
  else if (a.format == "csv")
    text = HorizonToCsv(profile);
  else
    text = HorizonToGeoJson(profile);
  if (!a.plot.empty()) {
    HorizonPlotOptions po;
    std::ostringstream t;
    t.precision(7);
    t << "Horizon from " << a.lat << ", " << a.lon << "  eye " << std::lround(observer.height_m) << " m"
      << "  step " << profile.azimuth_step_deg << " deg  k = " << profile.refraction;
    po.title = t.str();
    WriteImage(a.plot, PlotHorizon(profile, ridges, po));
  }
  WriteOutput(a.output, text);
  return 0;
}

}  // namespace horizonreg::cli
