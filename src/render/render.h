// SPDX-License-Identifier: MIT
// Predicted views of the terrain: what a camera at a pose should see
// (shaded, depth-cued terrain under a sky gradient), and a 360-degree
// panorama. Users compare these with their photos; the demo registers one.
#pragma once

#include "camera/camera.h"
#include "dem/terrain.h"
#include "geo/geodesy.h"

namespace cv {
class Mat;
}

namespace horizonreg {

struct RenderOptions {
  double max_distance_m = 100'000.0;       // Terrain farther than this is not drawn, > 0.
  double refraction = kDefaultRefraction;  // k of the lift k d^2 / (2 R), as for the horizon.
  double sun_azimuth_deg = 225.0;          // Light direction for the shading, degrees.
  double sun_elevation_deg = 35.0;         // degrees, in (0, 90].
  double haze_distance_m = 45'000.0;       // Aerial perspective: half the contrast is lost at ~0.7 x this, > 0.
  bool flat_sky = false;                   // Sky in one flat colour (BGR 255, 0, 255), for masks and tests.
  void Check() const;                      // Throws InvalidArgument naming the field.
};

// Renders the view of a pinhole camera (pose and intrinsics, DESIGN.md
// conventions) from `observer` (eye position, ellipsoidal height) over the
// terrain: 8-bit BGR, intrinsics.width x intrinsics.height. Algorithm: per
// azimuth column (half a pixel apart) a march outwards over the bilinear DEM
// surface (exact WGS84 positions at knots along the ray, refraction lift as
// ComputeHorizon) collects the visible bands of elevation angle with their
// distance and shade; each pixel looks up its ray's band. Earth curvature
// and refraction as in the horizon module, so the rendered skyline agrees
// with ComputeHorizon to the march step (~0.3 DEM spacings). Throws
// InvalidArgument for bad options or intrinsics. Thread-safe.
cv::Mat RenderView(const TerrainWindow& terrain, const GeodeticPoint& observer, const CameraPose& pose,
                   const CameraIntrinsics& intrinsics, const RenderOptions& options);

// Renders a 360-degree equirectangular panorama: x = azimuth (0 at the left
// edge, clockwise, width_px columns), y = elevation angle from max_elevation_deg
// (top) to min_elevation_deg (bottom), linear. Same shading as RenderView.
cv::Mat RenderPanorama(const TerrainWindow& terrain, const GeodeticPoint& observer, int width_px, int height_px,
                       double min_elevation_deg, double max_elevation_deg, const RenderOptions& options);

}  // namespace horizonreg
