// SPDX-License-Identifier: MIT
// `horizonreg demo`: the main job on built-in data. Until registration and
// the overlay land, it computes and plots the horizon of a real DEM that a
// Debian package ships (python-matplotlib-data: Jacksboro fault, Cumberland
// Mountains, TN, 3 arc-seconds), seen from a valley floor near its centre.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cli/commands.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "overlay/horizon_plot.h"
#include "util/errors.h"

namespace horizonreg::cli {

namespace {
constexpr const char* kJacksboro = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";
}

void AddDemoCommand(CLI::App& app, DemoArgs& a) {
  CLI::App* c = app.add_subcommand("demo", "Run the main job on built-in data (a DEM shipped by Debian)");
  c->add_option("--output-dir", a.output_dir, "Folder for the demo's pictures and files")->capture_default_str();
  c->add_option("--dem", a.dem, "DEM to use instead of matplotlib's jacksboro_fault_dem.npz");
}

int RunDemo(const DemoArgs& a) {
  const std::string dem = a.dem.empty() ? kJacksboro : a.dem;
  std::error_code ec;
  if (!std::filesystem::exists(dem, ec))
    throw IoError("demo: '" + dem + "' is missing; install Debian's python-matplotlib-data (make deps)");
  std::filesystem::create_directories(a.output_dir, ec);
  if (ec) throw IoError("demo: cannot create '" + a.output_dir + "': " + ec.message());

  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const Terrain terrain({dem});
  const GeodeticPoint centre = terrain.CenterOf(0);
  const TerrainWindow whole = terrain.ReadWindow(centre, 100'000.0);
  // Observer: the lowest post of the DEM's central part, a valley floor with
  // ridges all round.
  const DemGrid& g = whole.grids.at(0);
  size_t low = 0;
  float low_h = INFINITY;
  for (int r = g.height / 4; r < 3 * g.height / 4; ++r)
    for (int c = g.width / 4; c < 3 * g.width / 4; ++c) {
      const size_t k = static_cast<size_t>(r) * g.width + c;
      if (g.height_m[k] < low_h) low_h = g.height_m[k], low = k;
    }
  const int col = static_cast<int>(low % g.width), row = static_cast<int>(low / g.width);
  const double lat = g.LatAt(col, row), lon = g.LonAt(col, row);
  HorizonOptions options;
  const GeodeticPoint observer = ResolveObserver(whole, lat, lon, std::nullopt, std::nullopt);
  const auto t1 = Clock::now();
  const HorizonProfile profile = ComputeHorizon(whole, observer, options);
  const auto t2 = Clock::now();
  const auto ridges = ComputeRidges(whole, observer, options, RidgeOptions{});
  const auto t3 = Clock::now();

  const std::string json_path = (std::filesystem::path(a.output_dir) / "demo_horizon.json").string();
  const std::string png_path = (std::filesystem::path(a.output_dir) / "demo_horizon.png").string();
  WriteOutput(json_path, HorizonToJson(profile, ridges));
  HorizonPlotOptions po;
  char title[256];
  std::snprintf(title, sizeof(title), "Jacksboro fault DEM (Cumberland Mts, TN): horizon from %.5f, %.5f, eye %.0f m",
                lat, lon, observer.height_m);
  po.title = title;
  WriteImage(png_path, PlotHorizon(profile, ridges, po));

  int hi = 0, valid = 0;
  size_t ridge_points = 0;
  for (int i = 0; i < profile.size(); ++i) {
    if (!std::isfinite(profile.elevation_deg[i])) continue;
    ++valid;
    ridge_points += ridges[i].size();
    if (!(profile.elevation_deg[i] <= profile.elevation_deg[hi])) hi = i;
  }
  auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  std::printf("horizonreg demo: DEM %s (%d x %d posts)\n", dem.c_str(), g.width, g.height);
  std::printf("  observer      %.6f, %.6f, ground %.1f m, eye %.1f m\n", lat, lon,
              whole.HeightAt(lat, lon).value_or(NAN), observer.height_m);
  std::printf("  horizon       %d bins of %.2f deg, %d with terrain, %zu inner ridge points\n", profile.size(),
              profile.azimuth_step_deg, valid, ridge_points);
  std::printf("  highest       azimuth %.2f deg, elevation %.3f deg, %.1f km away\n", profile.AzimuthDeg(hi),
              profile.elevation_deg[hi], profile.distance_m[hi] / 1000.0);
  std::printf("  timing        load %.1f ms, horizon %.1f ms, ridges %.1f ms\n", ms(t1 - t0), ms(t2 - t1), ms(t3 - t2));
  std::printf("  wrote         %s\n                %s\n", png_path.c_str(), json_path.c_str());
  return 0;
}

}  // namespace horizonreg::cli
