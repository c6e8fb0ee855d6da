// SPDX-License-Identifier: MIT
// Pinhole camera: orientation (azimuth/yaw, pitch, roll) in the observer's
// ENU frame, intrinsics, and the exact projection of directions to pixels
// and back (geo/conventions.h, DESIGN.md).
#pragma once

#include <Eigen/Core>
#include <cmath>
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

// The same rotation for any scalar type (ceres::Jet for automatic
// derivatives), angles in radians: azimuth, pitch, roll.
template <typename T>
Eigen::Matrix<T, 3, 3> CamFromEnuRad(const T& yaw, const T& pitch, const T& roll) {
  using std::cos;
  using std::sin;
  const Eigen::Matrix<T, 3, 1> forward(sin(yaw) * cos(pitch), cos(yaw) * cos(pitch), sin(pitch));
  const Eigen::Matrix<T, 3, 1> right0(cos(yaw), -sin(yaw), T(0.0));
  const Eigen::Matrix<T, 3, 1> up0 = right0.cross(forward);
  // Roll: the right side goes down for positive roll.
  const Eigen::Matrix<T, 3, 1> right = cos(roll) * right0 - sin(roll) * up0;
  const Eigen::Matrix<T, 3, 1> up = sin(roll) * right0 + cos(roll) * up0;
  Eigen::Matrix<T, 3, 3> m;
  m.row(0) = right.transpose();
  m.row(1) = -up.transpose();  // image y points down
  m.row(2) = forward.transpose();
  return m;
}

// Inverse of CamFromEnu for a rotation matrix: azimuth in [0, 360), pitch in
// [-90, 90], roll in (-180, 180]. At pitch +-90 deg (gimbal lock) the roll is
// folded into the azimuth and returned as 0. Thread-safe.
CameraPose PoseFromCamFromEnu(const Eigen::Matrix3d& cam_from_enu);

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
