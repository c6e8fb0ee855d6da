// SPDX-License-Identifier: MIT
// `horizonreg locate`: where a photo was taken, from its skyline and the DEM
// alone (no GPS), then its registration there.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "dem/tiles.h"
#include "pipeline/camera_file.h"
#include "pipeline/locate.h"
#include "pipeline/register_photo.h"
#include "pipeline/report.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg::cli {

void AddLocateCommand(CLI::App& app, LocateArgs& a) {
  CLI::App* c = app.add_subcommand("locate", "Find where a photo was taken inside an area from its skyline (no GPS)");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format; several files form a mosaic");
  c->add_option("--dem-dir", a.dem_dir, "Folder of DEM tiles: those around the area are found by their extents");
  c->add_flag("--sea-level-fill", a.sea_level_fill, "Ground missing from every DEM file is the sea at 0 m");
  c->add_option("--area", a.area, "Search area LAT,LON,RADIUS_M (degrees, metres)")->required();
  c->add_option("--agl", a.agl, "Eye height above the ground, metres")->capture_default_str();
  c->add_option("--grid", a.grid, "Spacing of the coarse viewpoints, metres (default radius / 30, 100-400 m)");
  auto* hfov = c->add_option("--hfov", a.hfov, "Known horizontal opening angle, degrees (searched within +-3%)");
  auto* range =
      c->add_option("--hfov-range", a.hfov_range, "Opening angles to search, MIN:MAX degrees (default 10:120)");
  hfov->excludes(range);
  c->add_option("--camera", a.camera, "Known intrinsics (as `register --camera`); used exactly");
  c->add_flag("--pinhole", a.pinhole, "The photo has no lens distortion: do not fit k1");
  c->add_flag("--no-exif", a.no_exif, "Ignore the photo's EXIF (focal length, direction)");
  c->add_option("--max-distance", a.max_distance, "Terrain farther than this is ignored, metres")
      ->capture_default_str();
  c->add_option("--json", a.json, "Write the JSON here instead of stdout");
  c->add_option("--overlay", a.overlay, "Draw the overlay at the located pose over the photo into this PNG");
  AddMaxImageOption(*c, a.max_image_mpx);
  AddMaxDemOption(*c, a.max_dem_mb);
}

int RunLocate(const LocateArgs& a) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  LocateOptions lo;
  {
    const std::vector<std::string> f = SplitCsvLine(a.area);
    if (f.size() != 3) throw InvalidArgument("--area must be LAT,LON,RADIUS_M, got '" + a.area + "'");
    const auto lat = ParseDouble(Trim(f[0])), lon = ParseDouble(Trim(f[1])), r = ParseDouble(Trim(f[2]));
    if (!lat || !lon || !r) throw InvalidArgument("--area must be LAT,LON,RADIUS_M (numbers), got '" + a.area + "'");
    lo.lat_deg = *lat, lo.lon_deg = *lon, lo.radius_m = *r;
  }
  if (a.hfov && !(*a.hfov > 0 && *a.hfov < 170)) throw InvalidArgument("--hfov must be in (0, 170) degrees");
  if (a.grid) lo.grid_m = *a.grid;
  std::vector<std::string> warnings;
  const cv::Mat image = ReadImage(a.image, a.max_image_mpx * 1e6, &warnings);
  for (const std::string& w : warnings) std::cerr << "horizonreg: warning: " << w << "\n";
  PhotoOptions& po = lo.photo;
  if (!a.no_exif) po.exif = ReadExif(a.image);
  po.hfov_deg = a.hfov;
  if (!a.hfov_range.empty()) po.hfov_range_deg = ParseHfovRange(a.hfov_range);
  po.pinhole = a.pinhole;
  if (!a.camera.empty()) po.camera = ReadCameraFile(a.camera, image.cols, image.rows);
  lo.site.agl_m = a.agl;
  lo.site.max_distance_m = a.max_distance;
  lo.site.sea_level_fill = a.sea_level_fill;
  lo.site.max_dem_bytes = static_cast<size_t>(a.max_dem_mb * (1 << 20));
  lo.Check();
  const std::vector<std::string> dem =
      DemFilesFor(a.dem, a.dem_dir, lo.lat_deg, lo.lon_deg, lo.radius_m + lo.site.max_distance_m);
  ThreadPool pool(2);
  const LocateResult r = Locate(dem, image, lo, &pool);

  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  nlohmann::json j;
  if (r.site) {
    j = RegistrationReport(*r.site, r.registration, "locate", total_ms);
  } else {
    j = {{"status", "no_match"}, {"width", image.cols}, {"height", image.rows}};
  }
  if (!r.located) {
    j["status"] = "no_match";
    j["message"] = r.message;
  }
  if (r.located) {
    const LocateCandidate& c = r.candidates[0];
    // The spread of the viewpoints that fit as well, at least half the last step.
    const double sigma = std::max(r.grid_m / 64.0, c.position_rms_m);
    j["position"] = {{"lat", Rounded(c.lat_deg, 7)},
                     {"lon", Rounded(c.lon_deg, 7)},
                     {"eye_height_m", Rounded(r.site->observer().height_m, 2)},
                     {"sigma_east_m", Rounded(sigma, 1)},
                     {"sigma_north_m", Rounded(sigma, 1)},
                     {"sigma_up_m", Rounded(2.0, 1)},
                     {"observable", true}};
  }
  auto finite_or_null = [](double v) { return std::isfinite(v) ? nlohmann::json(Rounded(v, 2)) : nlohmann::json(nullptr); };
  nlohmann::json cands = nlohmann::json::array();
  for (const LocateCandidate& c : r.candidates) {
    nlohmann::json e = {{"lat", Rounded(c.lat_deg, 7)},
                        {"lon", Rounded(c.lon_deg, 7)},
                        {"profile_misfit_deg2", Rounded(c.cost, 4)},
                        {"coarse_misfit_deg2", Rounded(c.coarse_cost, 4)},
                        {"azimuth_deg", Rounded(c.azimuth_deg, 2)},
                        {"hfov_deg", Rounded(c.hfov_deg, 2)}};
    if (c.tried) {
      e["status"] = c.registered ? "registered" : "no_match";
      e["misfit"] = std::isfinite(c.misfit) ? nlohmann::json(Rounded(c.misfit, 4)) : nlohmann::json(nullptr);
      e["message"] = c.message;
      e["equal_fit"] = {{"position_spread_m", Rounded(c.position_spread_m, 1)},
                        {"orientation_spread_deg", Rounded(c.orientation_spread_deg, 3)}};
    }
    cands.push_back(e);
  }
  j["locate"] = {{"area", {{"lat", lo.lat_deg}, {"lon", lo.lon_deg}, {"radius_m", lo.radius_m}}},
                 {"grid_m", Rounded(r.grid_m, 1)},
                 {"profile_distinctiveness", finite_or_null(r.distinctiveness)},
                 {"distinctiveness", finite_or_null(r.registration_distinctiveness)},
                 {"viewpoints", {{"coarse", r.coarse_viewpoints}, {"fine", r.fine_viewpoints}}},
                 {"position_check_followed", r.followed_checks},
                 {"candidates", cands},
                 {"message", r.message}};
  j["timing_ms"]["locate"] = {{"dem", Rounded(r.dem_ms, 1)},       {"skyline", Rounded(r.skyline_ms, 1)},
                              {"coarse", Rounded(r.coarse_ms, 1)}, {"fine", Rounded(r.fine_ms, 1)},
                              {"register", Rounded(r.register_ms, 1)}};
  j["timing_ms"]["total"] = Rounded(total_ms, 1);
  if (!a.overlay.empty() && r.site) WriteImage(a.overlay, DrawRegistration(*r.site, image, r.registration, ""));
  WriteOutput(a.json.empty() ? "-" : a.json, j.dump(1) + "\n");
  return 0;
}

}  // namespace horizonreg::cli
