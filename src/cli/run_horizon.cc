// SPDX-License-Identifier: MIT
// `horizonreg horizon`: the 360-degree horizon at one point or many
// (--points). Also built without OpenCV into horizonreg-horizon
// (HORIZONREG_NO_PLOT), which the launcher runs unless --plot is given.
#include <CLI/CLI.hpp>
#include <charconv>
#include <chrono>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/output.h"
#include "dem/tiles.h"
#include "util/errors.h"
#include "util/text.h"
#include "util/thread_pool.h"
#ifndef HORIZONREG_NO_PLOT
#include "cli/image_io.h"
#include "overlay/horizon_plot.h"
#endif

namespace horizonreg::cli {

using nlohmann::json;

void AddHorizonCommand(CLI::App& app, HorizonArgs& a) {
  CLI::App* c = app.add_subcommand("horizon", "Compute the 360-degree terrain horizon from DEM file(s)");
  c->add_option("--dem", a.dem, "DEM file (any GDAL raster, or a matplotlib .npz); repeat for a mosaic");
  c->add_option("--dem-dir", a.dem_dir, "Folder of DEM tiles: those around the observer are found by their extents");
  c->add_flag("--sea-level-fill", a.sea_level_fill, "Ground missing from every DEM file is the sea at 0 m");
  auto* lat = c->add_option("--lat", a.lat, "Observer latitude, degrees (WGS84)");
  auto* lon = c->add_option("--lon", a.lon, "Observer longitude, degrees (WGS84)");
  auto* points = c->add_option("--points", a.points,
                               "CSV of observers (lat,lon[,id][,agl_m|alt_m]): one profile per point, in parallel, "
                               "from one DEM window (output: CSV rows id,...,azimuth_deg,elevation_deg,distance_m, or "
                               "a JSON array of horizon objects)");
  points->excludes(lat)->excludes(lon);
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the terrain, m (default 1.7)");
  auto* alt = c->add_option("--alt", a.alt, "Absolute eye altitude, m (as the DEM's heights)");
  agl->excludes(alt);
  c->add_option("--step", a.options.azimuth_step_deg, "Azimuth bin width and spacing, degrees; divides 360")
      ->capture_default_str();
  c->add_option("--max-distance", a.options.max_distance_m, "Ignore terrain farther than this, m")
      ->capture_default_str();
  c->add_option("--refraction", a.options.refraction, "Refraction coefficient k (0 = pure geometry)")
      ->capture_default_str();
  c->add_option("--threads", a.options.num_threads, "Threads (default 2; with --points all cores)")
      ->each([&a](const std::string&) { a.threads_given = true; });
  c->add_option("--format", a.format, "Output format")
      ->check(CLI::IsMember({"json", "csv", "geojson"}))
      ->capture_default_str();
  c->add_option("-o,--output", a.output, "Output file ('-' = stdout)")->capture_default_str();
  c->add_option("--plot", a.plot, "Also draw a panorama chart to this PNG");
  c->add_flag("--ridges", a.ridges, "Also compute the inner ridge lines (JSON output and plot)");
  AddMaxDemOption(*c, a.max_dem_mb);
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

namespace {

struct Point {
  std::string id;
  double lat = NAN, lon = NAN;
  std::optional<double> agl, alt;
};

std::vector<Point> ReadPoints(const std::string& path) {
  const std::string what = "--points";
  std::vector<Point> out;
  for (const auto& [n, r] : ReadCsvRecords(ReadTextFile(path, what, size_t{256} << 20), what, path,
                                           {"lat", "lon", "id", "name", "agl_m", "alt_m"})) {
    const auto bad = [&, n = n](const std::string& why) {
      throw InvalidArgument(what + " '" + path + "', line " + std::to_string(n) + ": " + why);
    };
    Point p;
    p.id = std::to_string(out.size() + 1);
    for (const auto& [h, cell] : r) {
      if (h == "id" || h == "name") {
        p.id = cell;
        continue;
      }
      const auto v = ParseDouble(cell);
      if (!v || !std::isfinite(*v)) bad(h + " '" + cell + "' is not a number");
      if (h == "lat") p.lat = *v;
      if (h == "lon") p.lon = *v;
      if (h == "agl_m") p.agl = *v;
      if (h == "alt_m") p.alt = *v;
    }
    if (!(std::abs(p.lat) <= 90.0) || !(std::abs(p.lon) <= 360.0)) bad("lat and lon are needed, within [-90, 90] and [-180, 360]");
    if (p.agl && p.alt) bad("give agl_m or alt_m, not both");
    out.push_back(p);
  }
  if (out.empty()) throw InvalidArgument(what + " '" + path + "': no points");
  return out;
}

// Profiles at many points: one DEM window around them all when they lie
// close together (else one per point, read one at a time: a Terrain is not
// thread-safe), the profiles computed in parallel on one pool.
int RunHorizonPoints(const HorizonArgs& a) {
  if (!a.plot.empty()) throw InvalidArgument("--plot draws one profile: not with --points");
  if (a.format == "geojson") throw InvalidArgument("--points writes csv or json");
  const std::vector<Point> points = ReadPoints(a.points);
  double lat0 = 0.0, lon0 = 0.0;
  for (const Point& p : points) lat0 += p.lat / points.size(), lon0 += p.lon / points.size();
  double spread = 0.0;
  const LocalFrame frame({lat0, lon0, 0.0});
  for (const Point& p : points) {
    const Eigen::Vector3d e = frame.EnuFromGeodetic({p.lat, p.lon, 0.0});
    spread = std::max(spread, std::hypot(e.x(), e.y()));
  }
  const double radius = a.options.max_distance_m + spread;
  const bool shared = spread <= a.options.max_distance_m;  // a window at most twice as wide as one point's
  Terrain terrain(shared ? DemFilesFor(a.dem, a.dem_dir, lat0, lon0, radius)
                               : DemFilesFor(a.dem, a.dem_dir, points[0].lat, points[0].lon, a.options.max_distance_m));
  terrain.set_max_window_bytes(static_cast<size_t>(a.max_dem_mb * (1 << 20)));
  if (!shared && !a.dem_dir.empty())
    throw InvalidArgument("--points spread over " + std::to_string(static_cast<int>(spread / 1000)) +
                          " km: with --dem-dir give points within --max-distance of their centre");
  std::unique_ptr<TerrainWindow> window;
  if (shared) {
    window = std::make_unique<TerrainWindow>(terrain.ReadWindow({lat0, lon0, 0.0}, radius));
    if (a.sea_level_fill) AddSeaLevel(*window, {lat0, lon0, 0.0}, radius);
  }
  const int threads = a.threads_given ? a.options.num_threads
                                      : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  ThreadPool pool(threads);
  HorizonOptions ho = a.options;
  ho.pool = nullptr;  // one point per thread: no nested sweep, no second pre-pass per point
  ho.num_threads = 1;
  std::vector<HorizonProfile> profiles(points.size());
  std::vector<std::string> errors(points.size());
  std::mutex terrain_mutex;
  pool.ParallelFor(points.size(), [&](size_t i, int) {
    const Point& p = points[i];
    try {
      if (shared) {
        profiles[i] = ComputeHorizon(*window, ResolveObserver(*window, p.lat, p.lon, p.agl, p.alt), ho);
      } else {
        TerrainWindow w;
        {
          std::lock_guard<std::mutex> lock(terrain_mutex);
          w = terrain.ReadWindow({p.lat, p.lon, 0.0}, a.options.max_distance_m);
        }
        if (a.sea_level_fill) AddSeaLevel(w, {p.lat, p.lon, 0.0}, a.options.max_distance_m);
        profiles[i] = ComputeHorizon(w, ResolveObserver(w, p.lat, p.lon, p.agl, p.alt), ho);
      }
    } catch (const Error& e) {
      errors[i] = e.what();
    }
  });
  for (size_t i = 0; i < points.size(); ++i)
    if (!errors[i].empty()) throw InvalidArgument("--points '" + a.points + "', point " + points[i].id + ": " + errors[i]);
  std::string text;
  if (a.format == "csv") {
    // The numbers as the JSON writes them (rounded, shortest form), without
    // a JSON value per cell: 1440 rows per point.
    const auto number = [&text](double v, int decimals) {
      const nlohmann::json r = Rounded(v, decimals);
      if (r.is_null()) return;
      char buf[32];
      const auto end = std::to_chars(buf, buf + sizeof(buf), r.get<double>()).ptr;
      text.append(buf, end);
      if (std::find_if(buf, end, [](char c) { return c == '.' || c == 'e'; }) == end) text += ".0";  // as JSON: 0.0
    };
    text = "id,lat,lon,eye_height_m,azimuth_deg,elevation_deg,distance_m\n";
    for (size_t i = 0; i < points.size(); ++i) {
      const HorizonProfile& p = profiles[i];
      std::string id = points[i].id;
      if (id.find_first_of(",\"") != std::string::npos) id = "\"" + id + "\"";
      std::ostringstream head;
      head.precision(10);
      head << id << ',' << points[i].lat << ',' << points[i].lon << ',' << Rounded(p.observer.height_m, 2) << ',';
      for (int b = 0; b < p.size(); ++b) {
        text += head.str();
        number(p.AzimuthDeg(b), 6);
        text += ',';
        number(p.elevation_deg[b], 5);
        text += ',';
        number(p.distance_m[b], 1);
        text += '\n';
      }
    }
  } else {
    json all = json::array();
    for (size_t i = 0; i < points.size(); ++i) {
      json j = json::parse(HorizonToJson(profiles[i], {}));
      j["id"] = points[i].id;
      all.push_back(std::move(j));
    }
    text = all.dump() + "\n";
  }
  WriteOutput(a.output, text);
  return 0;
}

}  // namespace

int RunHorizon(const HorizonArgs& a) {
  // Check everything before any work (STYLE.md section 6).
  a.options.Check();
  if (!a.points.empty()) return RunHorizonPoints(a);
  if (std::isnan(a.lat) || std::isnan(a.lon)) throw InvalidArgument("horizon: give --lat and --lon, or --points FILE");
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
  Terrain terrain(DemFilesFor(a.dem, a.dem_dir, a.lat, a.lon, a.options.max_distance_m));
  terrain.set_max_window_bytes(static_cast<size_t>(a.max_dem_mb * (1 << 20)));
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
#ifdef HORIZONREG_NO_PLOT
    throw InvalidArgument("--plot needs the full horizonreg (run through the horizonreg launcher)");
#else
    HorizonPlotOptions po;
    std::ostringstream t;
    t.precision(7);
    t << "Horizon from " << a.lat << ", " << a.lon << "  eye " << std::lround(observer.height_m) << " m"
      << "  step " << profile.azimuth_step_deg << " deg  k = " << profile.refraction;
    po.title = t.str();
    WriteImage(a.plot, PlotHorizon(profile, ridges, po));
#endif
  }
  WriteOutput(a.output, text);
  return 0;
}

}  // namespace horizonreg::cli
