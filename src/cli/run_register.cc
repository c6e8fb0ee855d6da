// SPDX-License-Identifier: MIT
// `horizonreg register`: camera azimuth, pitch, roll and focal length of a
// photo from its skyline and the DEM horizon at its position.
#include <CLI/CLI.hpp>
#include <iostream>
#include <chrono>
#include <future>
#include <nlohmann/json.hpp>
#include <memory>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "dem/tiles.h"
#include "match/register.h"
#include "overlay/overlay.h"
#include "pipeline/camera_file.h"
#include "pipeline/register_photo.h"
#include "pipeline/report.h"
#include "pipeline/site.h"
#include "sensors/sensors.h"
#include "skyline/skyline.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg::cli {

void AddRegisterCommand(CLI::App& app, RegisterArgs& a) {
  CLI::App* c = app.add_subcommand("register", "Recover the camera's azimuth, pitch, roll and focal length of a photo");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format; several files form a mosaic");
  c->add_option("--dem-dir", a.dem_dir, "Folder of DEM tiles: those around the camera are found by their extents");
  c->add_flag("--sea-level-fill", a.sea_level_fill, "Ground missing from every DEM file is the sea at 0 m");
  c->add_option("--lat", a.lat, "Camera latitude, degrees (default: --sensors or the photo's GPS EXIF)");
  c->add_option("--lon", a.lon, "Camera longitude, degrees");
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the ground, metres (default 1.7)");
  auto* alt = c->add_option("--alt", a.alt, "Eye altitude above the ellipsoid, metres");
  agl->excludes(alt);
  c->add_option("--sensors", a.sensors, "Compass/inclinometer readings (JSON, DESIGN.md) used as priors");
  c->add_option("--position-sigma", a.position_sigma,
                "How far the position may be off, metres, 1 sigma (default 1 for --lat/--lon, 10 for a GPS fix; "
                "with --refine-position the horizontal prior, default 15 for --lat/--lon, 10 for a GPS fix)")
      ->check(CLI::Range(0.0, 100000.0));
  c->add_flag("--refine-position", a.refine_position,
              "Also estimate the latitude, longitude and eye height within the position's prior (eye height 10 m, "
              "an EXIF altitude 20 m); the JSON gains a \"position\" block (DESIGN.md)");
  c->add_flag("--trust-position", a.trust_position,
              "Skip the check that the skyline does not fit clearly better from elsewhere (a wrong position); "
              "saves its time for a surveyed camera");
  auto* hfov = c->add_option("--hfov", a.hfov, "Known horizontal opening angle, degrees (searched within +-3%)");
  auto* range =
      c->add_option("--hfov-range", a.hfov_range, "Opening angles to search, MIN:MAX degrees (default 10:120)");
  hfov->excludes(range);
  c->add_option("--step", a.step, "Azimuth step of the DEM horizon, degrees (360 / step whole)")->capture_default_str();
  c->add_option("--refraction", a.refraction, "Refraction coefficient k")->capture_default_str();
  c->add_option("--max-distance", a.max_distance, "Terrain farther than this is ignored, metres")
      ->capture_default_str();
  c->add_option("--initial", a.initial,
                "Known approximate pose AZ,PITCH,ROLL,HFOV (degrees, fixed cameras): a registration more than 6 deg or "
                "10% of opening angle from it is refused; with --trust-position it is refined instead of searching");
  c->add_option("--camera", a.camera,
                "Known intrinsics: OpenCV calibration YAML/JSON or {\"focal_px\", \"cx_px\", \"cy_px\", \"k\": [...], "
                "\"p\": [...]} (DESIGN.md pixels); used exactly");
  c->add_option("--skyline", a.skyline,
                "Use this skyline JSON (as `skyline --json` writes it, e.g. traced by hand) instead of extracting one");
  c->add_flag("--pinhole", a.pinhole,
              "The photo has no lens distortion (rectified): do not fit k1 without a --camera file");
  c->add_flag("--no-exif", a.no_exif, "Ignore the photo's EXIF (GPS, focal length, direction)");
  c->add_option("--json", a.json, "Write the JSON here instead of stdout");
  c->add_option(
      "--skyline-out", a.skyline_out,
      "Write the skyline JSON: when registered, read again near the DEM horizon at the pose; else as extracted");
  c->add_option("--overlay", a.overlay, "Draw the overlay at the recovered pose over the photo into this PNG");
  c->add_option("--landmarks", a.landmarks, "Named peaks for the overlay labels (GeoJSON or CSV)");
  AddMaxImageOption(*c, a.max_image_mpx);
  AddMaxDemOption(*c, a.max_dem_mb);
}

int RunRegister(const RegisterArgs& a) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  // Prepare: check every input before computing.
  if (a.lat.has_value() != a.lon.has_value()) throw InvalidArgument("--lat and --lon go together");
  if (a.hfov && !(*a.hfov > 0 && *a.hfov < 170)) throw InvalidArgument("--hfov must be in (0, 170) degrees");
  std::vector<std::string> warnings;
  const cv::Mat image = ReadImage(a.image, a.max_image_mpx * 1e6, &warnings);
  for (const std::string& w : warnings) std::cerr << "horizonreg: warning: " << w << "\n";
  if (image.cols < 8 || image.rows < 8)
    throw InvalidArgument("image: '" + a.image + "' is " + std::to_string(image.cols) + " x " +
                          std::to_string(image.rows) + " pixels; register needs at least 8 x 8");
  PhotoOptions po;
  if (!a.sensors.empty()) po.sensors = ReadSensorJson(a.sensors);
  if (!a.no_exif) po.exif = ReadExif(a.image);
  const PhotoPosition position = ResolvePhotoPosition(a.lat, a.lon, a.agl, a.alt, po.sensors, po.exif, a.image);
  po.position_source = position.source;
  po.position_sigma_m = a.position_sigma;
  po.hfov_deg = a.hfov;
  if (!a.hfov_range.empty()) po.hfov_range_deg = ParseHfovRange(a.hfov_range);
  po.pinhole = a.pinhole;
  if (a.trust_position) po.check_position.reset();
  if (!a.camera.empty()) po.camera = ReadCameraFile(a.camera, image.cols, image.rows);
  if (!a.initial.empty()) po.initial = ParseInitialPose(a.initial);
  if (!a.skyline.empty()) po.skyline = ReadSkylineJson(a.skyline, image.cols, image.rows);
  if (a.refine_position) {
    if (a.position_sigma && !(*a.position_sigma > 0.0))
      throw InvalidArgument("--position-sigma must be > 0 with --refine-position");
    po.refine_position = DefaultPositionOptions(position.source, position.alt_m && position.source == "exif",
                                                a.position_sigma);
  }
  po.Check();
  SiteOptions so;
  so.agl_m = position.agl_m;
  so.alt_m = position.alt_m;
  so.refraction = a.refraction;
  so.azimuth_step_deg = a.step;
  so.max_distance_m = a.max_distance;
  so.sea_level_fill = a.sea_level_fill;
  so.max_dem_bytes = static_cast<size_t>(a.max_dem_mb * (1 << 20));
  so.Check();
  const std::vector<std::string> dem =
      DemFilesFor(a.dem, a.dem_dir, position.lat_deg, position.lon_deg, so.max_distance_m);
  const SkylineOptions sky_options = PhotoSkylineOptions(po);

  // The skyline runs on a second thread while the DEM loads.
  auto skyline_job = std::async(std::launch::async, [&] {
    const auto s0 = Clock::now();
    Skyline s = po.skyline ? *po.skyline : ExtractSkyline(image, sky_options);
    return std::make_pair(std::move(s), std::chrono::duration<double, std::milli>(Clock::now() - s0).count());
  });
  ThreadPool pool(2);
  std::unique_ptr<Site> site;
  try {
    site = std::make_unique<Site>(dem, position.lat_deg, position.lon_deg, so, &pool);
  } catch (...) {
    skyline_job.wait();
    throw;
  }
  auto [skyline, skyline_ms] = skyline_job.get();
  po.skyline = std::move(skyline);
  PhotoRegistration photo = RegisterPhoto(*site, image, po, &pool);
  photo.skyline_ms = skyline_ms;
  if (!a.overlay.empty()) WriteImage(a.overlay, DrawRegistration(*site, image, photo, a.landmarks));
  if (!a.skyline_out.empty())
    WriteOutput(a.skyline_out, SkylineJson(RegisteredSkyline(*site, image, photo)).dump() + "\n");
  const nlohmann::json j = RegistrationReport(*site, photo, position.source,
                                              std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  WriteOutput(a.json.empty() ? "-" : a.json, j.dump(1) + "\n");
  return 0;
}

}  // namespace horizonreg::cli
