// SPDX-License-Identifier: MIT
// Pose hypotheses from two point correspondences between the image skyline
// and the DEM horizon (paper, section 3.2).
#pragma once

#include <optional>
#include <vector>

#include "camera/camera.h"

namespace horizonreg {

// One image point: pixel position (DESIGN.md image coordinates).
struct ImagePoint {
  double x = 0.0, y = 0.0;
};
// One horizon point: azimuth (clockwise from north) and elevation angle, degrees.
struct HorizonPoint {
  double azimuth_deg = 0.0, elevation_deg = 0.0;
};

// The paper's hypothesis (roll assumed zero): eq. (5) azimuth, eq. (6) pitch
// (linearised), eq. (8) C_x and eq. (9) C_y, in pixels per degree.
struct PaperHypothesis {
  double azimuth_deg = 0.0;
  double pitch_deg = 0.0;
  double cx_px_per_deg = 0.0;
  double cy_px_per_deg = 0.0;
};

// Evaluates eq. (5), (6), (8), (9) for image points p1, p2 (x, y relative to
// the principal point cx, cy) matched to horizon points h1, h2. Eq. (5) and
// (8) are exact for the paper's spherical image, x = C_x sin(alpha - alpha_c)
// (C_x in pixels per radian, reported per degree); for a pinhole camera they
// are approximations (0.05 deg at +-13 deg off axis). nullopt when the points are
// degenerate (same column, same azimuth, x2 = 0, opposite order or more than
// 180 degrees apart). Thread-safe.
std::optional<PaperHypothesis> PaperHypothesisFromPairs(const ImagePoint& p1, const ImagePoint& p2,
                                                        const HorizonPoint& h1, const HorizonPoint& h2, double cx,
                                                        double cy);

struct PoseHypothesis {
  CameraPose pose;
  double focal_px = 0.0;
};

// Exact pinhole solutions with roll: each focal length in [min_focal_px,
// max_focal_px] for which the angle between the two pixel rays equals the
// angle between the two horizon directions (closed form: a quadratic in f^2;
// there are two when both points lie on one side of the centre and the range
// reaches very wide angles), each with the rotation that takes both
// rays onto both directions (triad on the bisectors). Empty when no focal
// length in the range fits. Principal point (cx, cy). Thread-safe.
std::vector<PoseHypothesis> TwoPointPoses(const ImagePoint& p1, const ImagePoint& p2, const HorizonPoint& h1,
                                          const HorizonPoint& h2, double cx, double cy, double min_focal_px,
                                          double max_focal_px);

}  // namespace horizonreg
