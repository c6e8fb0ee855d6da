// SPDX-License-Identifier: MIT
// One Run<Command>() per subcommand (STYLE.md: cli/main.cc is the dispatcher).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "skyline/skyline.h"

namespace CLI {
class App;
}

namespace horizonreg::cli {

struct HorizonArgs {
  std::vector<std::string> dem;
  std::string dem_dir, points;
  bool sea_level_fill = false;
  double lat = NAN, lon = NAN;
  std::optional<double> agl, alt;
  HorizonOptions options;
  std::string format = "json";
  std::string output = "-";
  std::string plot;
  bool ridges = false;
  bool threads_given = false;  // --threads was given (else --points uses every core)
  double max_dem_mb = 2048.0;
};
void AddHorizonCommand(CLI::App& app, HorizonArgs& args);
int RunHorizon(const HorizonArgs& args);

struct SkylineArgs {
  std::string image, json, debug;
  std::optional<double> roll;
  double max_image_mpx = 250.0;
};
void AddSkylineCommand(CLI::App& app, SkylineArgs& args);
int RunSkyline(const SkylineArgs& args);

struct RegisterArgs {
  std::string image;
  std::vector<std::string> dem;
  std::string dem_dir;
  bool sea_level_fill = false;
  std::optional<double> lat, lon, agl, alt, hfov, position_sigma;
  std::string sensors, hfov_range, json, overlay, landmarks, initial, camera, skyline, skyline_out;
  double refraction = kDefaultRefraction;
  double max_distance = 100'000.0;
  double step = 0.1;  // finer than `horizon`'s default: each bin holds its maximum, 0.25 deg bins bias pitch
  bool no_exif = false;
  bool refine_position = false;  // --refine-position
  bool trust_position = false;   // --trust-position: no position-consistency check
  bool pinhole = false;
  double max_image_mpx = 250.0, max_dem_mb = 2048.0;
};
void AddRegisterCommand(CLI::App& app, RegisterArgs& args);
int RunRegister(const RegisterArgs& args);

struct LocateArgs {
  std::string image, dem_dir, area, hfov_range, camera, json, overlay;
  std::vector<std::string> dem;
  std::optional<double> hfov, grid;
  double agl = 1.7;
  double max_distance = 100'000.0;
  bool pinhole = false, no_exif = false, sea_level_fill = false;
  double max_image_mpx = 250.0, max_dem_mb = 2048.0;
};
void AddLocateCommand(CLI::App& app, LocateArgs& args);
int RunLocate(const LocateArgs& args);

struct BatchArgs {
  std::string manifest, dem_dir, stations, output, csv, overlay_dir, landmarks, hfov_range;
  std::vector<std::string> dem;
  std::optional<double> hfov;
  std::optional<int> threads;
  double refraction = kDefaultRefraction;
  double max_distance = 100'000.0;
  double step = 0.1;
  bool pinhole = false, no_exif = false, no_progress = false, sea_level_fill = false, refine_position = false;
  bool skylines = false;  // --skylines
  bool check_every_photo = false;  // --check-every-photo
  std::optional<double> position_sigma;
  double max_image_mpx = 250.0, max_dem_mb = 2048.0;
};
void AddBatchCommand(CLI::App& app, BatchArgs& args);
int RunBatch(const BatchArgs& args);

struct OverlayArgs {
  std::string image, pose, landmarks, output, camera;
  std::vector<std::string> dem;
  bool no_ridges = false;
  double max_image_mpx = 250.0;
};
void AddOverlayCommand(CLI::App& app, OverlayArgs& args);
int RunOverlay(const OverlayArgs& args);

// A pose as `register --json` writes it.
struct CameraPoseFile {
  double lat = 0.0, lon = 0.0, eye_height_m = 0.0;
  CameraPose pose;
  int width = 0, height = 0;
  double focal_px = 0.0;
  CameraIntrinsics intrinsics;  // the "camera" block when present (lens, principal point), else a centred pinhole
};
CameraPoseFile ReadPoseFile(const std::string& path);

// A skyline JSON as `skyline --json` writes it (DESIGN.md): {"width",
// "height", "y": [y or null], "confidence": [...] (optional)}. Throws
// InvalidArgument naming the file when it is malformed or not for a
// width x height image.
Skyline ReadSkylineJson(const std::string& path, int width, int height);

struct RenderArgs {
  std::vector<std::string> dem;
  double lat = NAN, lon = NAN;
  std::optional<double> agl, alt;
  double azimuth = NAN, pitch = 0.0, roll = 0.0, hfov = 60.0;
  std::string size = "1024x683", landmarks, panorama, output, camera;
  double refraction = kDefaultRefraction;
  bool no_overlay = false;
};
void AddRenderCommand(CLI::App& app, RenderArgs& args);
int RunRender(const RenderArgs& args);
std::pair<int, int> ParseSize(const std::string& s);

struct TrackArgs {
  std::string input, sensors, calibration_in, calibration_out, poses, output, camera;
  std::vector<std::string> dem;
  double lat = NAN, lon = NAN;
  std::optional<double> agl, alt;
  double fps = 30.0;
  int max_frames = 0;
};
void AddTrackCommand(CLI::App& app, TrackArgs& args);
int RunTrack(const TrackArgs& args);

struct DemoArgs {
  std::string output_dir = ".";
  std::string dem;  // default: matplotlib's jacksboro_fault_dem.npz
  int seed = 0;
};
void AddDemoCommand(CLI::App& app, DemoArgs& args);
int RunDemo(const DemoArgs& args);

// Serialisations of a horizon (DESIGN.md "horizon JSON"; CSV; GeoJSON).
std::string HorizonToJson(const HorizonProfile& p, const std::vector<std::vector<Ridge>>& ridges);
std::string HorizonToCsv(const HorizonProfile& p);
std::string HorizonToGeoJson(const HorizonProfile& p);

}  // namespace horizonreg::cli
