// SPDX-License-Identifier: MIT
// Pinhole camera: orientation (azimuth/yaw, pitch, roll) in the observer's
// ENU frame, intrinsics, and the exact projection of directions to pixels
// and back (geo/conventions.h, DESIGN.md).
#pragma once

#include <Eigen/Core>
#include <optional>

namespace horizonreg {

struct CameraPose {
  double azimuth_deg = 0.0;  // optical axis, clockwise from true north
  double pitch_deg = 0.0;    // optical axis above the horizontal
  double roll_deg = 0.0;     // about the optical axis, positive = right side down
};

struct CameraIntrinsics {
  int width = 0, height = 0;  // pixels
  double focal_px = 0.0;      // (width / 2) / tan(hfov / 2)
  double cx = 0.0, cy = 0.0;  // principal point, pixels (default: image centre)

  // Square pixels, principal point at the image centre.
  static CameraIntrinsics FromHfov(int width, int height, double hfov_deg);
  double HfovDeg() const;
  void Check() const;  // Throws InvalidArgument naming the field.
};

// Rotation taking ENU direction vectors into the camera frame (x right,
// y down, z forward). Exact, any angles (at pitch +-90 deg the azimuth
// defines the image's up direction). Thread-safe.
Eigen::Matrix3d CamFromEnu(const CameraPose& pose);

// Pixel (x right, y down, origin at the top-left corner of the top-left
// pixel) of an ENU direction; nullopt behind the camera. No small-angle
// approximation.
std::optional<Eigen::Vector2d> ProjectEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                          const Eigen::Vector3d& dir_enu);
// Same, for an azimuth and an elevation angle in degrees.
std::optional<Eigen::Vector2d> ProjectAzEl(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                           double azimuth_deg, double elevation_deg);
// Unit ENU direction of the ray through a pixel position.
Eigen::Vector3d UnprojectToEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                               const Eigen::Vector2d& pixel);

}  // namespace horizonreg
