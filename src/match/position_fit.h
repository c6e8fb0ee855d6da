// SPDX-License-Identifier: MIT
// The camera's orientation and the observer's position fitted together
// (issue 15): near ridges move with the position, far ones with the
// orientation, so one skyline that shows both carries both. The horizon is
// exact at the position it was computed for and linear in a small move from
// there (HorizonPositionGradient); pipeline/position.h recomputes it at each
// new position.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/register.h"
#include "skyline/skyline.h"

namespace horizonreg {

// Per horizon bin, how its elevation angle changes when the observer moves
// by (east, north, up) metres in its ENU frame: radians per metre; zero
// where the bin holds no terrain. To first order the horizon terrain stays
// where it is (the envelope theorem: the silhouette point may slide along
// the terrain, but that changes the maximum only to second order), so a bin
// at distance d and elevation el rises by sin(el) cos(el) / d per metre
// towards it, falls by cos^2(el) / d per metre up, and the profile is
// carried sideways by 1 / d radians of azimuth per metre across
// (elevation slope / d; the slope from the neighbours at a similar
// distance, so an occlusion edge does not count as a slope). Good while
// the move is small against the distance. Thread-safe.
std::vector<Eigen::Vector3d> HorizonPositionGradient(const HorizonProfile& horizon);

// Result of FitPoseAndPosition.
struct PoseAndPositionFit {
  CameraPose pose;                         // optical axis
  double focal_px = 0.0;
  double k1 = 0.0;                                       // radial distortion (the start's when held)
  Eigen::Vector3d step_enu_m = Eigen::Vector3d::Zero();  // the move from where the horizon was computed
  // Covariance of (yaw, pitch, roll in radians, focal px, east, north, up in
  // metres) with the prior, scaled by the inliers' misfit when above 1 and
  // by the share of independent DEM samples among the columns (k1, when
  // fitted, marginalised).
  Eigen::Matrix<double, 7, 7> covariance = Eigen::Matrix<double, 7, 7>::Identity();
  double cost = 0.0;        // robust cost (mean chi^2 over the columns, truncated at the gate) at the result
  double inlier_share = 0.0;  // columns inside the gate at the result (linearised horizon)
  int columns = 0;
};

// Robust Gauss-Newton (iteratively reweighted, the one-sided DEM loss and
// the outlier mixture of Register) of yaw, pitch, roll, focal length (held
// when fix_focal or the lens is known) and the observer's move, starting
// from `start`, `focal_px` and `k1` (k1 fitted when free_k1, under
// options.distortion_prior_sigma about 0, else held) at the position where
// `horizon` was computed, which lies `offset_enu_m` from the prior's centre;
// the prior is Gaussian with `prior_sigma_enu_m` (each > 0) per axis about
// that centre. The horizon under a move comes from HorizonPositionGradient.
// `options`: intrinsics, noise, outlier share, the DEM error model (its
// position term is the current position uncertainty) and refine_columns;
// `flattening_scale` as Registration::dem. The step is clamped to
// 3 prior sigmas from the centre. `free_axes` (1 free, 0 held, per east,
// north, up) holds axes where they are; all held fits the orientation
// alone: the cost of the position where the horizon was computed. `prior_weight` (in (0, 1]) weakens the prior in the
// steps (a proposal under an inflated noise model), not in the covariance. Levenberg-Marquardt: a step is taken when
// the robust objective (the truncated chi^2 of the columns on the linearised horizon and the prior's) falls. Throws
// InvalidArgument for bad inputs. Thread-safe.
PoseAndPositionFit FitPoseAndPosition(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start,
                                      double focal_px, double k1, bool free_k1, bool fix_focal,
                                      const Eigen::Vector3d& offset_enu_m, const Eigen::Vector3d& prior_sigma_enu_m,
                                      const RegistrationOptions& options, double flattening_scale, int iterations = 6,
                                      const Eigen::Vector3d& free_axes = Eigen::Vector3d::Ones(),
                                      double prior_weight = 1.0);

}  // namespace horizonreg
