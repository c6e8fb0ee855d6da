// SPDX-License-Identifier: MIT
// Camera: orientation (azimuth/yaw, pitch, roll) in the observer's ENU frame,
// intrinsics (focal length, principal point, OpenCV lens distortion), and the
// exact projection of directions to pixels and back (geo/conventions.h,
// DESIGN.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

namespace horizonreg {

struct CameraPose {
  double azimuth_deg = 0.0;  // optical axis, clockwise from true north
  double pitch_deg = 0.0;    // optical axis above the horizontal
  double roll_deg = 0.0;     // about the optical axis, positive = right side down
};

// Lens distortion: OpenCV's model (Brown-Conrady with the rational radial
// term) on normalised coordinates (x, y) = (X / Z, Y / Z) of the camera frame:
//   r2 = x^2 + y^2,
//   radial = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3),
//   x_d = x radial + 2 p1 x y + p2 (r2 + 2 x^2),
//   y_d = y radial + p1 (r2 + 2 y^2) + 2 p2 x y,
// then pixel = (cx + fx x_d, cy + fy y_d). All zero: a pinhole. The model is
// used only inside the radius where it is radially monotonic
// (ValidRadius()); beyond it (a polynomial lens folds back) a direction has
// no pixel.
class LensDistortion {
 public:
  LensDistortion() = default;
  // k = {k1..k6} (missing ones 0), p = {p1, p2}. Throws InvalidArgument when
  // a coefficient is not finite or |value| > 100.
  LensDistortion(const std::vector<double>& k, const std::vector<double>& p);
  // Radial only (k1, k2, k3).
  static LensDistortion Radial(double k1, double k2 = 0.0, double k3 = 0.0);

  bool IsIdentity() const { return identity_; }
  const std::array<double, 6>& k() const { return k_; }
  const std::array<double, 2>& p() const { return p_; }
  // Normalised radius (sqrt(x^2 + y^2) of the undistorted point) up to
  // which the model is monotonic; infinite for the identity.
  double ValidRadius() const { return valid_radius_; }

  // Distorted normalised coordinates of an undistorted point; any scalar
  // type (ceres::Jet). No range check.
  template <typename T>
  Eigen::Matrix<T, 2, 1> Distort(const T& x, const T& y) const {
    const T r2 = x * x + y * y;
    const T radial = (1.0 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[2]))) / (1.0 + r2 * (k_[3] + r2 * (k_[4] + r2 * k_[5])));
    return {x * radial + 2.0 * p_[0] * x * y + p_[1] * (r2 + 2.0 * x * x),
            y * radial + p_[0] * (r2 + 2.0 * y * y) + 2.0 * p_[1] * x * y};
  }
  // Undistorted normalised coordinates of a distorted point (fixed-point
  // iterations, then Newton; |error| < 1e-12 inside ValidRadius()).
  // nullopt when it does not converge (outside the valid region).
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& distorted) const;

 private:
  std::array<double, 6> k_{};
  std::array<double, 2> p_{};
  bool identity_ = true;
  double valid_radius_ = INFINITY;
};

struct CameraIntrinsics {
  int width = 0, height = 0;  // pixels
  double focal_px = 0.0;      // fx: (width / 2) / tan(hfov / 2) for a pinhole centred camera
  double aspect = 1.0;        // fy / fx (1: square pixels)
  double cx_px = 0.0, cy_px = 0.0;  // principal point (DESIGN.md pixel coordinates; default: image centre)
  LensDistortion distortion;        // none by default

  // Square pixels, principal point at the image centre, no distortion.
  static CameraIntrinsics FromHfov(int width, int height, double hfov_deg);
  // Opening angle of a centred pinhole with this focal length.
  double HfovDeg() const;
  double FocalYPx() const { return focal_px * aspect; }
  // Principal point at the image centre and no distortion.
  bool IsCentredPinhole() const;
  // Normalised camera coordinates (X / Z, Y / Z) of a pixel (distortion
  // removed) and back; nullopt outside the lens model's valid region.
  std::optional<Eigen::Vector2d> NormalizedFromPixel(const Eigen::Vector2d& pixel) const;
  std::optional<Eigen::Vector2d> PixelFromNormalized(const Eigen::Vector2d& xy) const;
  // The same intrinsics for the image resized to new_width x new_height.
  CameraIntrinsics Resized(int new_width, int new_height) const;
  void Check() const;  // Throws InvalidArgument naming the field.
};

// hfov <-> focal length of a centred pinhole `width` pixels wide (DESIGN.md):
// focal_px = (width / 2) / tan(hfov / 2). The one place this is written.
double FocalFromHfovPx(double hfov_deg, double width_px);
double HfovFromFocalDeg(double focal_px, double width_px);

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

// The orientation of the ray through the image centre (W / 2, H / 2) of a
// camera at `pose`: azimuth and pitch of that ray, and the roll of the
// camera turned (by the smallest rotation) to look along it. Equal to `pose`
// when the principal point is at the centre and the lens has no distortion;
// DESIGN.md reports it as "center_ray". Thread-safe.
CameraPose CenterRayPose(const CameraPose& pose, const CameraIntrinsics& k);
// Inverse: the optical axis' pose of a camera whose centre ray has the
// orientation `center_ray` (e.g. a pose measured on the image centre).
CameraPose AxisPoseFromCenterRay(const CameraPose& center_ray, const CameraIntrinsics& k);

// Inverse of CamFromEnu for a rotation matrix: azimuth in [0, 360), pitch in
// [-90, 90], roll in (-180, 180]. At pitch +-90 deg (gimbal lock) the roll is
// folded into the azimuth and returned as 0. Thread-safe.
CameraPose PoseFromCamFromEnu(const Eigen::Matrix3d& cam_from_enu);

// Pixel (x right, y down, origin at the top-left corner of the top-left
// pixel) of an ENU direction, through the lens distortion; nullopt behind
// the camera or outside the lens model's valid region. No small-angle
// approximation.
std::optional<Eigen::Vector2d> ProjectEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                          const Eigen::Vector3d& dir_enu);
// Same, for an azimuth and an elevation angle in degrees.
std::optional<Eigen::Vector2d> ProjectAzEl(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                           double azimuth_deg, double elevation_deg);
// Unit ENU direction of the ray through a pixel position (distortion
// removed; a pixel outside the lens model's valid region is taken as a
// pinhole's).
Eigen::Vector3d UnprojectToEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                               const Eigen::Vector2d& pixel);

}  // namespace horizonreg
