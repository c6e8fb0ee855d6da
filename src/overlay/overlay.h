// SPDX-License-Identifier: MIT
// The AR overlay (paper, section 4.5 and Fig. 10-11) drawn over a photo or a
// rendered view at a camera pose: DEM horizon and inner ridge lines coloured
// by distance, artificial horizon, vertical axis, ground-plane grid, compass
// tape with N/NE/E... labels, azimuth/pitch/roll read-outs and landmark
// labels (name, elevation, distance) that do not collide.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "overlay/landmarks.h"

namespace horizonreg {

struct OverlayOptions {
  bool horizon = true;             // DEM silhouette
  bool ridges = true;              // inner ridge lines (when given)
  bool artificial_horizon = true;  // 0 deg elevation line
  bool vertical_axis = true;
  bool ground_grid = true;
  bool compass = true;
  bool readout = true;
  bool landmarks = true;
  double eye_height_m = kDefaultEyeHeightM;  // for the ground-plane grid, > 0
  std::string caption;                       // extra line in the read-out box
  void Check() const;
};

struct OverlayInput {
  const HorizonProfile* horizon = nullptr;                  // required
  const std::vector<std::vector<Ridge>>* ridges = nullptr;  // optional, per horizon bin
  std::vector<ResolvedLandmark> landmarks;                  // drawn when visible and in view
};

// Draws the overlay over a copy of `image` (8-bit, 1/3/4 channels; the
// result is BGR) for a camera with `pose` and `intrinsics` (sized like the
// image). Line widths and fonts scale with the image width so that 640 px
// and 4000 px images read alike. Landmark labels are placed greedily, most
// important (nearest to the horizon line, highest) first, in tiers above the
// silhouette; a label that would overlap another is dropped. Throws
// InvalidArgument for bad options, a missing horizon or an image whose size
// differs from the intrinsics. Thread-safe.
struct DrawnLabel {
  std::string text;
  double x = 0.0, y = 0.0;  // the landmark's pixel (the marker), image coordinates
};
struct OverlayResult {
  cv::Mat image;                   // BGR
  std::vector<DrawnLabel> labels;  // landmarks labelled, in drawing order
};
OverlayResult DrawOverlay(const cv::Mat& image, const CameraPose& pose, const CameraIntrinsics& intrinsics,
                          const OverlayInput& input, const OverlayOptions& options);

// `text` broken at spaces into lines that each fit within `max_width_px`
// when drawn with OpenCV's FONT_HERSHEY_SIMPLEX at `font_scale` and
// `thickness` (a word longer than the width gets a line of its own); the
// lines joined by single spaces give the text back with its runs of spaces
// closed up. At most `max_lines` (> 0): the last of them ends in "..." when
// text was left over. Empty text: no lines.
std::vector<std::string> WrapText(const std::string& text, double font_scale, int thickness, int max_width_px,
                                  int max_lines);

// Labels a 360-degree equirectangular panorama (render/render.h: x =
// azimuth from 0 at the left edge, y = elevation from max_elevation_deg at the
// top to min_elevation_deg at the bottom): compass ticks every 15 deg with
// N/NE/E... names, and the visible landmarks. Returns a BGR copy.
cv::Mat DrawPanoramaLabels(const cv::Mat& panorama, double min_elevation_deg, double max_elevation_deg,
                           const std::vector<ResolvedLandmark>& landmarks);

}  // namespace horizonreg
