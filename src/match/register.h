// SPDX-License-Identifier: MIT
// Registration (paper, sections 3.2-3.3): camera azimuth, pitch, roll and
// focal length from the image skyline and the 360-degree DEM horizon, with
// no calibration and no initial orientation, and an honest "no match".
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "skyline/skyline.h"

namespace horizonreg {

// Compass and inclinometer readings used as priors (DESIGN.md "Sensor
// readings"). Any field may be absent.
struct SensorPrior {
  std::optional<double> compass_deg;    // azimuth of the optical axis, degrees
  std::optional<double> pitch_deg;      // inclinometer pitch, degrees
  std::optional<double> roll_deg;       // inclinometer roll, degrees (conventions.h)
  double compass_sigma_deg = 15.0;      // 1-sigma compass error (phones: 5-30 deg), > 0
  double inclinometer_sigma_deg = 2.0;  // 1-sigma inclinometer error, > 0
  double gate_sigmas = 3.0;             // Hypotheses farther than this many sigmas are dropped, > 0.
  void Check() const;
};

struct RegistrationOptions {
  double min_hfov_deg = 10.0;  // Horizontal opening angles searched, degrees, 0 < min <= max < 170.
  double max_hfov_deg = 120.0;
  double max_abs_roll_deg = 30.0;        // Hypotheses with more roll are dropped (without an inclinometer), degrees.
  int image_extrema = 7;                 // Most prominent image peaks and dips paired into hypotheses, >= 2.
  int horizon_extrema = 70;              // Most prominent DEM peaks and dips of each kind, >= 2.
  double min_image_prominence_px = 1.5;  // Image extrema below this are noise, pixels (scaled up for large images).
  double min_horizon_prominence_deg = 0.03;  // DEM extrema below this are noise, degrees.
  int coarse_columns = 24;                   // Skyline columns scored per hypothesis, >= 8.
  int quick_columns = 120;                   // Skyline columns for refining candidates, >= 8.
  int refine_columns = 300;                  // Skyline columns in the final least squares, >= 8.
  int candidates = 8;                        // Distinct best hypotheses given the paper's linear corrections, >= 2.
  int refined_candidates = 4;                // ... of which the best this many get the least squares, >= 2.
  double inlier_px = 3.0;                    // A column fits when within this many pixels (per 1000 px of image width).
  int num_threads = 2;  // Threads scoring and refining hypotheses, >= 1 (same result for any count).
  // The no-match decision (a wrong pose reported as registered is the worst outcome):
  double min_visible_fraction = 0.15;  // of the image columns with a skyline value
  double min_inlier_fraction = 0.80;   // of the visible columns within inlier_px at the refined pose
  double max_rms_px = 1.5;             // RMS of the inlier columns (per 1000 px of width)
  double min_ambiguity_ratio = 1.75;   // second-best distinct pose's cost over the best's
  SensorPrior prior;
  void Check() const;  // Throws InvalidArgument naming the field.
};

struct Registration {
  bool registered = false;
  std::string message;  // why not registered, or a short summary
  CameraPose pose;      // meaningful when a best pose exists (also for no_match, for diagnosis)
  double focal_px = 0.0;
  double hfov_deg = 0.0;
  double rms_px = NAN;  // RMS distance of the inlier columns to the projected horizon (near field down-weighted)
  double inlier_fraction = 0.0;         // visible columns within inlier_px, near-field columns (< ~400 m) down-weighted
  double ex_px = NAN, ey_px = NAN;      // paper eq. (13), (14): RMS horizontal and vertical differences
  double ambiguity_ratio = 0.0;         // cost of the best distinct alternative over the best's (inf if none)
  double second_inlier_fraction = 0.0;  // share of the columns that alternative fits
  double azimuth_sigma_deg = NAN, pitch_sigma_deg = NAN, roll_sigma_deg = NAN, focal_sigma_px = NAN;
  int hypotheses = 0;  // hypotheses scored after the constraints
  int image_extrema = 0, horizon_extrema = 0;
  CameraIntrinsics Intrinsics(int width, int height) const;
};

// The factor of the pixel tolerances (inlier_px, max_rms_px) for an image
// `width` pixels wide: per 1000 px, at least 1.
double ToleranceScale(int width);

// Registers a skyline (skyline module) against a horizon profile computed at
// the camera's position. Extrema of both (match/extrema.h); hypotheses from
// pairs of them (paper eq. 5, 6, 8, 9, generalised to roll by the exact
// two-point solution in match/hypothesis.h), pruned by the opening-angle
// range and the priors; the robust error of eq. (10) over the visible
// columns; the linear corrections of eq. (11)-(14); then a robust (Cauchy)
// least-squares fit of azimuth, pitch, roll and focal length with the exact
// pinhole projection (Ceres), with sigmas from its covariance. Deterministic.
// Throws InvalidArgument for bad options or an empty skyline/profile.
// Thread-safe.
Registration Register(const Skyline& skyline, const HorizonProfile& horizon, const RegistrationOptions& options);

// Tracking: refines a pose known approximately (the previous frame's, within
// a few pixels) against the skyline, without any hypothesis search: the same
// robust least squares, statistics and acceptance tests as Register (no
// ambiguity test: nothing else was searched). `fix_focal` keeps focal_px.
// Throws InvalidArgument for bad options or inputs. Thread-safe.
Registration RefinePose(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start, double focal_px,
                        bool fix_focal, const RegistrationOptions& options);

// Signed pixel distance from the image point (x, y) to the horizon projected
// with `pose` and focal `focal_px` (principal point at the centre of a
// width x height image), measured across the projected silhouette: positive
// when the point lies below it (in the terrain). For diagnostics and tests.
double HorizonDistancePx(const HorizonProfile& horizon, const CameraPose& pose, double focal_px, int width, int height,
                         double x, double y);

// Per image column, the y where the projected DEM horizon crosses the
// column's centre (bisection on the pixel ray's elevation against the
// horizon's at the ray's azimuth, to 1e-6 px); NaN when the column does not
// cross it within [-2 H, 3 H]. What a perfect skyline extractor would find
// for this pose. Thread-safe.
std::vector<double> ProjectedHorizonRows(const HorizonProfile& horizon, const CameraPose& pose,
                                         const CameraIntrinsics& intrinsics);

}  // namespace horizonreg
