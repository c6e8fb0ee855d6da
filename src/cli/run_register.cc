// SPDX-License-Identifier: MIT
// `horizonreg register`: camera azimuth, pitch, roll and focal length of a
// photo from its skyline and the DEM horizon at its position.
#include <CLI/CLI.hpp>
#include <chrono>
#include <future>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "cli/commands.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "cli/site.h"
#include "match/register.h"
#include "overlay/overlay.h"
#include "pipeline/camera_file.h"
#include "sensors/sensors.h"
#include "skyline/skyline.h"
#include "track/track.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg::cli {

void AddRegisterCommand(CLI::App& app, RegisterArgs& a) {
  CLI::App* c = app.add_subcommand("register", "Recover the camera's azimuth, pitch, roll and focal length of a photo");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format; several files form a mosaic")->required();
  c->add_option("--lat", a.lat, "Camera latitude, degrees (default: --sensors or the photo's GPS EXIF)");
  c->add_option("--lon", a.lon, "Camera longitude, degrees");
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the ground, metres (default 1.7)");
  auto* alt = c->add_option("--alt", a.alt, "Eye altitude above the ellipsoid, metres");
  agl->excludes(alt);
  c->add_option("--sensors", a.sensors, "Compass/inclinometer readings (JSON, DESIGN.md) used as priors");
  c->add_option("--position-sigma", a.position_sigma,
                "How far the position may be off, metres, 1 sigma (default 1 for --lat/--lon, 10 for a GPS fix)")
      ->check(CLI::Range(0.0, 100000.0));
  auto* hfov = c->add_option("--hfov", a.hfov, "Known horizontal opening angle, degrees (searched within +-3%)");
  auto* range =
      c->add_option("--hfov-range", a.hfov_range, "Opening angles to search, MIN:MAX degrees (default 10:120)");
  hfov->excludes(range);
  c->add_option("--step", a.step, "Azimuth step of the DEM horizon, degrees (360 / step whole)")->capture_default_str();
  c->add_option("--refraction", a.refraction, "Refraction coefficient k")->capture_default_str();
  c->add_option("--max-distance", a.max_distance, "Terrain farther than this is ignored, metres")
      ->capture_default_str();
  c->add_option("--initial", a.initial,
                "Known approximate pose AZ,PITCH,ROLL,HFOV (degrees): refine it instead of searching (fixed cameras)");
  c->add_option("--camera", a.camera,
                "Known intrinsics: OpenCV calibration YAML/JSON or {\"focal_px\", \"cx_px\", \"cy_px\", \"k\": [...], "
                "\"p\": [...]} (DESIGN.md pixels); used exactly");
  c->add_option("--skyline", a.skyline,
                "Use this skyline JSON (as `skyline --json` writes it, e.g. traced by hand) instead of extracting one");
  c->add_flag("--pinhole", a.pinhole,
              "The photo has no lens distortion (rectified): do not fit k1 without a --camera file");
  c->add_flag("--no-exif", a.no_exif, "Ignore the photo's EXIF (GPS, focal length, direction)");
  c->add_option("--json", a.json, "Write the JSON here instead of stdout");
  c->add_option("--overlay", a.overlay, "Draw the overlay at the recovered pose over the photo into this PNG");
  c->add_option("--landmarks", a.landmarks, "Named peaks for the overlay labels (GeoJSON or CSV)");
}

namespace {

std::pair<double, double> ParseRange(const std::string& s) {
  const auto colon = s.find(':');
  double lo = NAN, hi = NAN;
  try {
    if (colon == std::string::npos) throw std::invalid_argument("no colon");
    size_t used = 0;
    lo = std::stod(s.substr(0, colon), &used);
    if (used != colon) throw std::invalid_argument("trailing");
    const std::string rest = s.substr(colon + 1);
    hi = std::stod(rest, &used);
    if (used != rest.size()) throw std::invalid_argument("trailing");
  } catch (const std::exception&) {
    throw InvalidArgument("--hfov-range '" + s + "': expected MIN:MAX in degrees, e.g. 30:60");
  }
  if (!(lo > 0 && hi >= lo && hi < 170)) throw InvalidArgument("--hfov-range '" + s + "': need 0 < MIN <= MAX < 170");
  return {lo, hi};
}

// The prior 1-sigma of a pose given with --initial, degrees (a search
// constrained to about +-3 sigma around it).
constexpr double kInitialSigmaDeg = 2.0;

double Ms(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

int RunRegister(const RegisterArgs& a) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  // Prepare: check every input before computing.
  if (a.lat.has_value() != a.lon.has_value()) throw InvalidArgument("--lat and --lon go together");
  if (a.hfov && !(*a.hfov > 0 && *a.hfov < 170)) throw InvalidArgument("--hfov must be in (0, 170) degrees");
  const cv::Mat image = ReadImage(a.image);
  SensorReading sensors;
  if (!a.sensors.empty()) sensors = ReadSensorJson(a.sensors);
  const SensorReading exif = a.no_exif ? SensorReading{} : ReadExif(a.image);

  std::optional<double> lat = a.lat, lon = a.lon;
  std::string position_source = "arguments";
  if (!lat && sensors.lat_deg && sensors.lon_deg)
    lat = sensors.lat_deg, lon = sensors.lon_deg, position_source = "sensors";
  if (!lat && exif.lat_deg && exif.lon_deg) lat = exif.lat_deg, lon = exif.lon_deg, position_source = "exif";
  if (!lat)
    throw InvalidArgument("register: no camera position: give --lat and --lon ('" + a.image + "' has no GPS EXIF)");
  if (!(std::abs(*lat) <= 90.0) || !(std::abs(*lon) <= 360.0)) throw InvalidArgument("register: invalid --lat/--lon");
  std::optional<double> agl = a.agl, alt = a.alt;
  if (!agl && !alt && sensors.agl_m) agl = sensors.agl_m;
  if (!agl && !alt && position_source == "exif" && exif.alt_m) alt = exif.alt_m;

  RegistrationOptions ro;
  std::string fov_source = "default";
  if (a.hfov) {
    ro.min_hfov_deg = *a.hfov * 0.97, ro.max_hfov_deg = std::min(169.0, *a.hfov * 1.03), fov_source = "--hfov";
  } else if (!a.hfov_range.empty()) {
    std::tie(ro.min_hfov_deg, ro.max_hfov_deg) = ParseRange(a.hfov_range);
    fov_source = "--hfov-range";
  } else if (exif.focal_35mm) {
    const double h = HfovFromFocal35mm(*exif.focal_35mm, image.cols, image.rows);
    ro.min_hfov_deg = std::max(1.0, h * 0.9), ro.max_hfov_deg = std::min(169.0, h * 1.1), fov_source = "exif";
  }
  ro.estimate_distortion = !a.pinhole;
  if (!a.camera.empty()) ro.known_intrinsics = ReadCameraFile(a.camera, image.cols, image.rows);
  // How far the observer's given position may be off (the DEM error model):
  // coordinates given as arguments are taken as surveyed (1 m), a GPS fix
  // from sensors or EXIF as a phone's (10 m); an altitude as given (1 m, EXIF
  // 20 m), a height above the DEM as that DEM's error under the observer (2 m).
  ro.dem_error.position_sigma_m = a.position_sigma.value_or(position_source == "arguments" ? 1.0 : 10.0);
  ro.dem_error.height_sigma_m = alt ? (position_source == "exif" ? 20.0 : 1.0) : 2.0;
  ro.prior.compass_deg = sensors.compass_deg ? sensors.compass_deg : exif.compass_deg;
  if (!sensors.compass_deg && exif.compass_deg) ro.prior.compass_sigma_deg = 20.0;
  ro.prior.pitch_deg = sensors.pitch_deg;
  ro.prior.roll_deg = sensors.roll_deg;
  ro.Check();
  HorizonOptions ho;
  ho.refraction = a.refraction;
  ho.azimuth_step_deg = a.step;
  ho.max_distance_m = a.max_distance;
  ho.Check();
  SkylineOptions so;
  so.roll_hint_deg = sensors.roll_deg;
  so.Check();

  struct InitialPose {
    double azimuth_deg, pitch_deg, roll_deg, hfov_deg;
  };
  std::optional<InitialPose> initial;
  if (!a.initial.empty()) {
    double v[4];
    char tail = 0;
    if (std::sscanf(a.initial.c_str(), "%lf,%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &v[3], &tail) != 4 ||
        !(v[3] > 0 && v[3] < 170) || !(std::abs(v[1]) <= 90) || !(std::abs(v[2]) <= 90) || !std::isfinite(v[0]))
      throw InvalidArgument("--initial '" + a.initial + "': expected AZ,PITCH,ROLL,HFOV in degrees");
    initial = InitialPose{v[0], v[1], v[2], v[3]};
  }
  std::optional<Skyline> given_skyline;
  if (!a.skyline.empty()) given_skyline = ReadSkylineJson(a.skyline, image.cols, image.rows);

  // The skyline runs on a second thread while the DEM loads.
  auto skyline_job = std::async(std::launch::async, [&] {
    const auto s0 = Clock::now();
    Skyline s = given_skyline ? *given_skyline : ExtractSkyline(image, so);
    return std::make_pair(std::move(s), Ms(s0, Clock::now()));
  });
  const auto h0 = Clock::now();
  HorizonProfile profile;
  std::optional<Site> site;
  try {
    site = LoadSite(a.dem, *lat, *lon, agl, alt, ho.max_distance_m);
    profile = ComputeHorizon(site->window, site->observer, ho);
  } catch (...) {
    skyline_job.wait();
    throw;
  }
  const double horizon_ms = Ms(h0, Clock::now());
  const auto [skyline, skyline_ms] = skyline_job.get();
  const auto m0 = Clock::now();
  Registration r;
  if (a.initial.empty()) {
    r = RegisterImage(image, skyline, profile, ro);  // with a second look at a near miss
  } else {
    // A known approximate pose (a fixed camera, a pose a few degrees off):
    // the search constrained to it (priors of a few degrees, the opening
    // angle within 5%), else the graduated local fit from it, which starts
    // at a noise scale of 50 px per 1000 (about 2.5 deg at a 50-deg opening
    // angle).
    const CameraPose start{WrapAzimuthDeg(initial->azimuth_deg), initial->pitch_deg, initial->roll_deg};
    RegistrationOptions constrained = ro;
    constrained.prior.compass_deg = start.azimuth_deg;
    constrained.prior.pitch_deg = start.pitch_deg;
    constrained.prior.roll_deg = start.roll_deg;
    constrained.prior.compass_sigma_deg = kInitialSigmaDeg;
    constrained.prior.inclinometer_sigma_deg = kInitialSigmaDeg;
    if (!a.hfov && a.hfov_range.empty())
      constrained.min_hfov_deg = initial->hfov_deg * 0.95, constrained.max_hfov_deg = std::min(169.0, initial->hfov_deg * 1.05);
    r = RegisterImage(image, skyline, profile, constrained);
    if (!r.registered)
      r = RefinePose(skyline, profile, start, FocalFromHfovPx(initial->hfov_deg, image.cols),
                     !a.hfov_range.empty() || a.hfov, ro, 50.0);
  }
  const double match_ms = Ms(m0, Clock::now());

  nlohmann::json j;
  j["status"] = r.registered ? "registered" : "no_match";
  j["message"] = r.message;
  j["observer"] = {{"lat", Rounded(profile.observer.lat_deg, 7)},
                   {"lon", Rounded(profile.observer.lon_deg, 7)},
                   {"eye_height_m", Rounded(profile.observer.height_m, 2)},
                   {"source", position_source}};
  j["width"] = image.cols;
  j["height"] = image.rows;
  const auto pose_field = [&](double v, int decimals) { return r.registered ? Rounded(v, decimals) : nullptr; };
  j["azimuth_deg"] = pose_field(r.pose.azimuth_deg, 4);
  j["pitch_deg"] = pose_field(r.pose.pitch_deg, 4);
  j["roll_deg"] = pose_field(r.pose.roll_deg, 4);
  j["hfov_deg"] = pose_field(r.hfov_deg, 4);
  j["center_ray"] = {{"azimuth_deg", pose_field(r.center_ray.azimuth_deg, 4)},
                     {"elevation_deg", pose_field(r.center_ray.pitch_deg, 4)}};
  j["focal_px"] = pose_field(r.focal_px, 2);
  j["cx_px_per_deg"] = pose_field(DegToRad(r.focal_px), 3);
  j["cy_px_per_deg"] = pose_field(DegToRad(r.focal_px), 3);
  j["azimuth_sigma_deg"] = pose_field(r.azimuth_sigma_deg, 4);
  j["pitch_sigma_deg"] = pose_field(r.pitch_sigma_deg, 4);
  j["roll_sigma_deg"] = pose_field(r.roll_sigma_deg, 4);
  {
    const CameraIntrinsics& k = r.intrinsics;
    nlohmann::json cam = {{"source", ro.known_intrinsics ? "file" : "fitted"}};
    if (k.width > 0) {
      cam["focal_px"] = Rounded(k.focal_px, 2);
      cam["fy_px"] = Rounded(k.FocalYPx(), 2);
      cam["cx_px"] = Rounded(k.cx_px, 2);
      cam["cy_px"] = Rounded(k.cy_px, 2);
      nlohmann::json kk = nlohmann::json::array(), pp = nlohmann::json::array();
      for (double v : k.distortion.k()) kk.push_back(Rounded(v, 5));
      for (double v : k.distortion.p()) pp.push_back(Rounded(v, 5));
      cam["k"] = kk;
      cam["p"] = pp;
    }
    cam["k1_estimated"] = r.distortion_estimated;
    cam["k1_sigma"] = Rounded(r.k1_sigma, 4);
    j["camera"] = cam;
    j["dem"] = {{"post_spacing_m", Rounded(r.dem.post_spacing_m, 1)},
                {"horizon_distance_m", Rounded(r.dem.horizon_distance_m, 0)},
                {"expected_flattening_px", Rounded(r.dem.expected_flattening_px, 2)},
                {"skyline_above_dem_px", Rounded(r.dem.skyline_above_dem_px, 2)},
                {"dem_explained_fraction", Rounded(r.dem.dem_explained_fraction, 3)},
                {"flattening_scale", Rounded(r.dem.flattening_scale, 2)}};
  }
  j["rms_px"] = Rounded(r.rms_px, 3);
  j["model_rms_px"] = Rounded(r.model_rms_px, 3);
  j["ex_px"] = Rounded(r.ex_px, 3);
  j["ey_px"] = Rounded(r.ey_px, 3);
  j["inlier_fraction"] = Rounded(r.inlier_fraction, 3);
  j["ambiguity_ratio"] = Rounded(std::min(r.ambiguity_ratio, 1e6), 2);
  j["second_inlier_fraction"] = Rounded(r.second_inlier_fraction, 3);
  j["evidence"] = {{"misfit", Rounded(r.misfit, 3)},
                   {"second_misfit", Rounded(r.second_misfit, 3)},
                   {"informative_columns", Rounded(r.informative_columns, 1)},
                   {"independent_inliers", Rounded(r.independent_inliers, 1)},
                   {"nats", Rounded(r.evidence_nats, 1)}};
  j["hypotheses"] = r.hypotheses;
  nlohmann::json alternatives = nlohmann::json::array();
  for (const PoseCandidate& c : r.candidates)
    alternatives.push_back({{"azimuth_deg", Rounded(c.pose.azimuth_deg, 3)},
                            {"pitch_deg", Rounded(c.pose.pitch_deg, 3)},
                            {"roll_deg", Rounded(c.pose.roll_deg, 3)},
                            {"hfov_deg", Rounded(HfovFromFocalDeg(c.focal_px, image.cols), 3)},
                            {"cost", Rounded(c.cost, 4)},
                            {"inlier_fraction", Rounded(c.inlier_fraction, 3)}});
  j["candidates"] = alternatives;
  j["extrema"] = {{"image", r.image_extrema}, {"horizon", r.horizon_extrema}};
  j["skyline_visible_fraction"] = Rounded(static_cast<double>(skyline.VisibleCount()) / skyline.width, 3);
  j["hfov_search_deg"] = {Rounded(ro.min_hfov_deg, 2), Rounded(ro.max_hfov_deg, 2), fov_source};
  nlohmann::json prior = nlohmann::json::object();
  if (ro.prior.compass_deg) prior["compass_deg"] = Rounded(*ro.prior.compass_deg, 3);
  if (ro.prior.pitch_deg) prior["pitch_deg"] = Rounded(*ro.prior.pitch_deg, 3);
  if (ro.prior.roll_deg) prior["roll_deg"] = Rounded(*ro.prior.roll_deg, 3);
  j["priors"] = prior;

  if (!a.overlay.empty()) {
    std::ostringstream caption;
    caption.precision(3);
    caption << std::fixed;
    cv::Mat drawn;
    if (r.registered) {
      caption << "registered: rms " << r.rms_px << " px, sigma az " << r.azimuth_sigma_deg << " pitch "
              << r.pitch_sigma_deg << " deg";
      OverlayOptions oo;
      oo.caption = caption.str();
      oo.eye_height_m = site->EyeAboveGroundM();
      const auto ridges = ComputeRidges(site->window, site->observer, ho, RidgeOptions{});
      drawn = DrawOverlay(image, r.pose, r.Intrinsics(image.cols, image.rows),
                          {&profile, &ridges, OverlayLandmarks(*site, profile, a.landmarks, ho.refraction)}, oo)
                  .image;
    } else {
      caption << "no match: " << r.message;
      drawn = DrawSkylineDebug(image, skyline);
      const double s = std::max(0.6, image.cols / 1000.0);
      cv::putText(drawn, caption.str(), {static_cast<int>(10 * s), static_cast<int>(30 * s)}, cv::FONT_HERSHEY_SIMPLEX,
                  0.6 * s, cv::Scalar(0, 0, 0), static_cast<int>(4 * s), cv::LINE_AA);
      cv::putText(drawn, caption.str(), {static_cast<int>(10 * s), static_cast<int>(30 * s)}, cv::FONT_HERSHEY_SIMPLEX,
                  0.6 * s, cv::Scalar(255, 255, 255), std::max(1, static_cast<int>(1.5 * s)), cv::LINE_AA);
    }
    WriteImage(a.overlay, drawn);
  }
  j["timing_ms"] = {{"horizon", Rounded(horizon_ms, 1)},
                    {"skyline", Rounded(skyline_ms, 1)},
                    {"match", Rounded(match_ms, 1)},
                    {"total", Rounded(Ms(t0, Clock::now()), 1)}};
  WriteOutput(a.json.empty() ? "-" : a.json, j.dump(1) + "\n");
  return 0;
}

}  // namespace horizonreg::cli
