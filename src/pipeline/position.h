// SPDX-License-Identifier: MIT
// Position refinement (issue 15): the observer's latitude, longitude and eye
// height estimated jointly with the camera's orientation, within the prior
// of where the position came from. Near ridges carry the position, far ones
// the orientation; a horizon that is all far away leaves the position to
// its prior, and this says so.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>

#include "geo/geodesy.h"
#include "horizon/horizon.h"
#include "match/register.h"
#include "skyline/skyline.h"
#include "util/thread_pool.h"

namespace horizonreg {

class Site;

struct PositionOptions {
  double horizontal_sigma_m = 15.0;  // prior 1-sigma of east and north about the given position, metres, > 0
  double vertical_sigma_m = 10.0;    // prior 1-sigma of the eye height, metres, > 0
  int max_horizons = 6;              // exact horizons computed at new positions (trial steps), >= 1
  double converged_m = 0.5;          // stop when a step moves less than this, metres, > 0
  // An axis is observable when its posterior sigma is below this share of its prior sigma, in (0, 1].
  double observable_ratio = 0.5;
  // When only some axes are observable, search again with the others held
  // at the start (their estimate then stays the prior's centre).
  bool hold_weak_axes = false;
  // Scan the eye height at +-1.5 prior sigmas (2 exact horizons) before
  // the joint search, which starts from the best.
  bool height_scan = true;
  void Check() const;  // Throws InvalidArgument naming the field.
};

// The prior by the position's source: coordinates given as arguments (a
// published webcam position, a map pick) 15 m, a GPS fix from sensors or
// EXIF 10 m; the eye height 10 m, an EXIF altitude 20 m.
// `horizontal_sigma_m` overrides the horizontal prior when given.
PositionOptions DefaultPositionOptions(const std::string& position_source, bool exif_altitude,
                                       std::optional<double> horizontal_sigma_m);

struct PositionEstimate {
  GeodeticPoint given;     // the prior's centre (the site's observer)
  GeodeticPoint observer;  // the estimate (= given when not observable), height above the ellipsoid
  Eigen::Vector3d offset_enu_m = Eigen::Vector3d::Zero();  // observer - given in the given ENU frame
  Eigen::Vector3d prior_sigma_enu_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_enu_m = Eigen::Vector3d::Zero();  // posterior 1-sigma (the prior's when not observable)
  bool observable_axis[3] = {false, false, false};        // east, north, up
  bool observable = false;  // every axis observable
  // Correlation of east, north, up with azimuth, pitch, roll, focal length
  // (rows, columns) in the joint fit; zero when not observable.
  Eigen::Matrix<double, 3, 4> correlation = Eigen::Matrix<double, 3, 4>::Zero();
  double azimuth_sigma_deg = NAN, pitch_sigma_deg = NAN;  // orientation sigmas with the position free
  int horizons = 0;           // exact horizons computed
  std::string message;        // how it went, for the report
  HorizonProfile horizon;     // at `observer`
  double ms = 0.0;            // time spent
};

// Refines the position of `site`'s observer for a photo whose skyline was
// registered (or nearly: `first.focal_px` > 0) at the site's horizon with
// `options`: the joint Gauss-Newton of match/position_fit.h, the exact
// horizon recomputed at each new position from the site's DEM window
// (on `pool`), the DEM error model's position term shrinking from the
// prior to the posterior. Not observable (no axis below observable_ratio of
// its prior): the given position is kept. The caller registers again at
// the estimate (RegisterPhoto does) so that the decision's gates apply
// there. `start_offset_enu_m` (with `start_horizon`, the horizon there)
// starts the search away from the prior's centre, where `first` was
// registered (an eye given below the terrain starts above it). Throws
// InvalidArgument for bad options. Thread-safe.
PositionEstimate RefinePosition(const Site& site, const Skyline& skyline, const Registration& first,
                                const RegistrationOptions& options, const PositionOptions& position_options,
                                ThreadPool* pool = nullptr,
                                const Eigen::Vector3d& start_offset_enu_m = Eigen::Vector3d::Zero(),
                                const HorizonProfile* start_horizon = nullptr);

// Where the search starts: the given eye, or above the terrain when it is
// given below it (kDefaultEyeHeightM above the ground), in metres up.
Eigen::Vector3d PositionSearchStart(const Site& site);

}  // namespace horizonreg
