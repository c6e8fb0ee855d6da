// SPDX-License-Identifier: MIT
// `horizonreg render`: the predicted view of the terrain for a pose, with the
// overlay, and optionally a 360-degree panorama.
#include <CLI/CLI.hpp>
#include <algorithm>

#include "cli/commands.h"
#include "cli/image_io.h"
#include "pipeline/site.h"
#include "overlay/overlay.h"
#include "pipeline/camera_file.h"
#include "render/render.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg::cli {

void AddRenderCommand(CLI::App& app, RenderArgs& a) {
  CLI::App* c = app.add_subcommand("render", "Render the predicted view of the terrain for a pose");
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format")->required();
  c->add_option("--lat", a.lat, "Camera latitude, degrees")->required();
  c->add_option("--lon", a.lon, "Camera longitude, degrees")->required();
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the ground, metres (default 1.7)");
  c->add_option("--alt", a.alt, "Eye altitude above the ellipsoid, metres")->excludes(agl);
  c->add_option("--azimuth", a.azimuth, "Camera azimuth, degrees clockwise from north")->required();
  c->add_option("--pitch", a.pitch, "Camera pitch, degrees up")->capture_default_str();
  c->add_option("--roll", a.roll, "Camera roll, degrees (right side down)")->capture_default_str();
  c->add_option("--hfov", a.hfov, "Horizontal opening angle, degrees")->capture_default_str();
  c->add_option("--size", a.size, "Image size WxH")->capture_default_str();
  c->add_option("--camera", a.camera,
                "Known intrinsics (OpenCV calibration YAML/JSON or camera JSON) for the view, at --size: the lens "
                "replaces --hfov");
  c->add_option("--landmarks", a.landmarks, "Named peaks for the labels (GeoJSON or CSV)");
  c->add_flag("--no-overlay", a.no_overlay, "The terrain only, without the overlay");
  c->add_option("--panorama", a.panorama, "Also write a 360-degree panorama PNG here");
  c->add_option("--refraction", a.refraction, "Refraction coefficient k")->capture_default_str();
  c->add_option("-o,--output", a.output, "Output PNG")->required();
}

std::pair<int, int> ParseSize(const std::string& s) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') || w < 8 || h < 8 ||
      w > 20000 || h > 20000)
    throw InvalidArgument("--size '" + s + "': expected WxH, each 8 to 20000, e.g. 1024x683");
  return {w, h};
}

int RunRender(const RenderArgs& a) {
  const auto [w, h] = ParseSize(a.size);
  if (!(a.hfov > 0 && a.hfov < 170)) throw InvalidArgument("--hfov must be in (0, 170) degrees");
  if (!(std::abs(a.pitch) <= 90)) throw InvalidArgument("--pitch must be within [-90, 90]");
  if (!std::isfinite(a.azimuth) || !std::isfinite(a.roll)) throw InvalidArgument("--azimuth and --roll must be finite");
  RenderOptions ro;
  ro.refraction = a.refraction;
  ro.Check();
  SiteOptions so;
  so.agl_m = a.agl;
  so.alt_m = a.alt;
  so.refraction = a.refraction;
  so.max_distance_m = ro.max_distance_m;
  ThreadPool pool(2);
  const Site site(a.dem, a.lat, a.lon, so, &pool);
  const CameraPose pose{WrapAzimuthDeg(a.azimuth), a.pitch, a.roll};
  const CameraIntrinsics k = a.camera.empty() ? CameraIntrinsics::FromHfov(w, h, a.hfov) : ReadCameraFile(a.camera, w, h);
  cv::Mat view = RenderView(site.window(), site.observer(), pose, k, ro);
  const HorizonProfile& horizon = site.horizon();
  const auto landmarks = OverlayLandmarks(site, a.landmarks);
  if (!a.no_overlay) {
    const auto& ridges = site.ridges();
    OverlayOptions o;
    o.eye_height_m = site.EyeAboveGroundM();
    o.caption = "predicted view (DEM render)";
    view = DrawOverlay(view, pose, k, {&horizon, &ridges, landmarks}, o).image;
  }
  if (!a.panorama.empty()) {
    const auto [lo, hi] = std::minmax_element(horizon.elevation_deg.begin(), horizon.elevation_deg.end());
    const double min_el = std::max(-60.0, *lo - 3.0), max_el = std::min(80.0, *hi + 4.0);
    const int pw = 3600, ph = std::clamp(static_cast<int>(std::lround((max_el - min_el) * 10.0)), 120, 1800);
    const cv::Mat pano = DrawPanoramaLabels(RenderPanorama(site.window(), site.observer(), pw, ph, min_el, max_el, ro),
                                            min_el, max_el, landmarks);
    WriteImage(a.panorama, pano);
  }
  WriteImage(a.output, view);
  return 0;
}

}  // namespace horizonreg::cli
