// SPDX-License-Identifier: MIT
// `horizonreg overlay`: the AR overlay over a photo at a registered pose.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/image_io.h"
#include "pipeline/site.h"
#include "overlay/overlay.h"
#include "pipeline/camera_file.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg::cli {

void AddOverlayCommand(CLI::App& app, OverlayArgs& a) {
  CLI::App* c = app.add_subcommand("overlay", "Draw the AR overlay over a photo at a pose (register --json output)");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--pose", a.pose, "Pose JSON as `register --json` writes it")->required();
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format")->required();
  c->add_option("--landmarks", a.landmarks, "Named peaks: GeoJSON points (name, ele) or CSV name,lat,lon[,ele]");
  c->add_option("-o,--output", a.output, "Output PNG")->required();
  c->add_flag("--no-ridges", a.no_ridges, "Do not draw the inner ridge lines");
  c->add_option("--camera", a.camera,
                "Known intrinsics (OpenCV calibration YAML/JSON or camera JSON); default: the pose file's camera");
  AddMaxImageOption(*c, a.max_image_mpx);
}

namespace {

double Number(const nlohmann::json& j, const char* key, const std::string& path) {
  if (!j.contains(key) || !j[key].is_number())
    throw InvalidArgument("pose: '" + path + "' has no number '" + key + "'");
  return j[key].get<double>();
}

}  // namespace

CameraPoseFile ReadPoseFile(const std::string& path) {
  const nlohmann::json j = ParseJson(ReadTextFile(path, "pose", size_t{64} << 20), "pose", path);
  // (json::value() throws a type_error for a non-object or a non-string
  // status, which would end as an unexplained exit 1: found by fuzz_pose.)
  if (!j.is_object()) throw InvalidArgument("pose: '" + path + "' is not a JSON object");
  if (j.contains("status") && j["status"] != "registered")
    throw InvalidArgument("pose: '" + path + "' holds no pose (status " +
                          (j["status"].is_string() ? j["status"].get<std::string>() : j["status"].dump()) + ")");
  if (!j.contains("observer") || !j["observer"].is_object())
    throw InvalidArgument("pose: '" + path + "' has no observer");
  CameraPoseFile p;
  p.lat = Number(j["observer"], "lat", path);
  p.lon = Number(j["observer"], "lon", path);
  p.eye_height_m = Number(j["observer"], "eye_height_m", path);
  p.pose = {Number(j, "azimuth_deg", path), Number(j, "pitch_deg", path), Number(j, "roll_deg", path)};
  const double width = Number(j, "width", path), height = Number(j, "height", path);
  p.focal_px = Number(j, "focal_px", path);
  constexpr double kMaxSide = std::numeric_limits<int>::max();  // checked before the cast to int
  if (!(p.focal_px > 0 && std::isfinite(p.focal_px)) || !(width >= 1 && width <= kMaxSide) ||
      !(height >= 1 && height <= kMaxSide))
    throw InvalidArgument("pose: '" + path + "' has an invalid focal_px, width or height");
  p.width = static_cast<int>(width);
  p.height = static_cast<int>(height);
  p.intrinsics = CameraIntrinsics::FromHfov(p.width, p.height, 60.0);
  p.intrinsics.focal_px = p.focal_px;
  if (j.contains("camera") && j["camera"].is_object() && j["camera"].contains("focal_px")) {
    // The lens the registration used (register writes its "camera" block in
    // this camera-file layout).
    try {
      nlohmann::json cam = j["camera"];
      cam["width"] = p.width;
      cam["height"] = p.height;
      p.intrinsics = CameraFromJson(cam, p.width, p.height, path);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("pose: '" + path + "': camera: " + e.what());
    }
  }
  return p;
}

int RunOverlay(const OverlayArgs& a) {
  const CameraPoseFile p = ReadPoseFile(a.pose);
  std::vector<std::string> warnings;
  const cv::Mat image = ReadImage(a.image, a.max_image_mpx * 1e6, &warnings);
  for (const std::string& w : warnings) std::cerr << "horizonreg: warning: " << w << "\n";
  // The photo may be a resized copy of the registered one.
  const CameraIntrinsics k = a.camera.empty() ? p.intrinsics.Resized(image.cols, image.rows)
                                              : ReadCameraFile(a.camera, image.cols, image.rows);
  SiteOptions so;
  so.alt_m = p.eye_height_m;
  ThreadPool pool(2);
  const Site site(a.dem, p.lat, p.lon, so, &pool);
  OverlayInput in{&site.horizon(), a.no_ridges ? nullptr : &site.ridges(), OverlayLandmarks(site, a.landmarks)};
  OverlayOptions o;
  o.eye_height_m = site.EyeAboveGroundM();
  WriteImage(a.output, DrawOverlay(image, p.pose, k, in, o).image);
  return 0;
}

}  // namespace horizonreg::cli
