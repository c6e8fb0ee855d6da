// SPDX-License-Identifier: MIT
// The options of `horizonreg track`. Both executables declare them: horizonreg
// (for --help and checking) and horizonreg-track, which runs the command (it
// alone links OpenCV's video I/O and its ~100 shared libraries; see
// track_main.cc).
#include <CLI/CLI.hpp>

#include "cli/commands.h"

namespace horizonreg::cli {

void AddTrackCommand(CLI::App& app, TrackArgs& a) {
  CLI::App* c = app.add_subcommand("track", "Follow the camera through a video: poses per frame and an overlay video");
  c->add_option("input", a.input, "Video file, image pattern (frame_%04d.jpg) or camera index")->required();
  c->add_option("--dem", a.dem, "DEM file(s), any GDAL format")->required();
  c->add_option("--lat", a.lat, "Camera latitude, degrees")->required();
  c->add_option("--lon", a.lon, "Camera longitude, degrees")->required();
  auto* agl = c->add_option("--agl", a.agl, "Eye height above the ground, metres (default 1.7)");
  c->add_option("--alt", a.alt, "Eye altitude above the ellipsoid, metres")->excludes(agl);
  c->add_option("--sensors", a.sensors, "Per-frame compass/inclinometer log (CSV or JSON array, DESIGN.md)");
  c->add_option("--fps", a.fps, "Frame rate when the input does not say (image sequences)")->capture_default_str();
  c->add_option("--calibration-in", a.calibration_in, "Start from this sensor calibration (JSON)");
  c->add_option("--calibration-out", a.calibration_out, "Write the sensor calibration estimated here (JSON)");
  c->add_option("--poses", a.poses, "Write frame,azimuth_deg,pitch_deg,roll_deg,hfov_deg,source here (CSV)");
  c->add_option("-o,--output", a.output, "Overlay video (.mp4 or .avi)");
  c->add_option("--max-frames", a.max_frames, "Stop after this many frames (0: all)")->capture_default_str();
  c->add_option("--camera", a.camera,
                "Known intrinsics (OpenCV calibration YAML/JSON or camera JSON); default: fitted at the first "
                "registration and kept");
}

}  // namespace horizonreg::cli
