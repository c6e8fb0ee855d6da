// SPDX-License-Identifier: MIT
#include "camera/camera.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

CameraIntrinsics CameraIntrinsics::FromHfov(int width, int height, double hfov_deg) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.focal_px = (width / 2.0) / std::tan(DegToRad(hfov_deg) / 2.0);
  k.cx = width / 2.0;
  k.cy = height / 2.0;
  return k;
}

double CameraIntrinsics::HfovDeg() const { return RadToDeg(2.0 * std::atan((width / 2.0) / focal_px)); }

void CameraIntrinsics::Check() const {
  auto fail = [](const char* field, double v, const char* rule) {
    std::ostringstream m;
    m << "CameraIntrinsics::" << field << " = " << v << "; violated: " << rule;
    throw InvalidArgument(m.str());
  };
  if (width < 1) fail("width", width, "width >= 1");
  if (height < 1) fail("height", height, "height >= 1");
  if (!(focal_px > 0.0) || !std::isfinite(focal_px)) fail("focal_px", focal_px, "0 < focal_px < inf");
  if (!std::isfinite(cx)) fail("cx", cx, "finite");
  if (!std::isfinite(cy)) fail("cy", cy, "finite");
}

Eigen::Matrix3d CamFromEnu(const CameraPose& pose) {
  return CamFromEnuRad(DegToRad(pose.azimuth_deg), DegToRad(pose.pitch_deg), DegToRad(pose.roll_deg));
}

CameraPose PoseFromCamFromEnu(const Eigen::Matrix3d& cam_from_enu) {
  const Eigen::Vector3d right = cam_from_enu.row(0).transpose();
  const Eigen::Vector3d forward = cam_from_enu.row(2).transpose();
  CameraPose pose;
  pose.pitch_deg = RadToDeg(std::asin(std::clamp(forward.z(), -1.0, 1.0)));
  const double horizontal = std::hypot(forward.x(), forward.y());
  if (horizontal < 1e-12) {  // looking straight up or down: the image's up direction sets the azimuth
    const Eigen::Vector3d down = cam_from_enu.row(1).transpose();
    const Eigen::Vector3d towards = forward.z() > 0 ? down : Eigen::Vector3d(-down);
    pose.azimuth_deg = WrapAzimuthDeg(RadToDeg(std::atan2(towards.x(), towards.y())));
    return pose;
  }
  const double yaw = std::atan2(forward.x(), forward.y());
  pose.azimuth_deg = WrapAzimuthDeg(RadToDeg(yaw));
  const Eigen::Vector3d right0(std::cos(yaw), -std::sin(yaw), 0.0);
  const Eigen::Vector3d up0 = right0.cross(forward);
  pose.roll_deg = RadToDeg(std::atan2(-right.dot(up0), right.dot(right0)));
  return pose;
}

std::optional<Eigen::Vector2d> ProjectEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                          const Eigen::Vector3d& dir_enu) {
  const Eigen::Vector3d c = cam_from_enu * dir_enu;
  if (!(c.z() > 1e-12 * c.norm())) return std::nullopt;
  return Eigen::Vector2d(k.cx + k.focal_px * c.x() / c.z(), k.cy + k.focal_px * c.y() / c.z());
}

std::optional<Eigen::Vector2d> ProjectAzEl(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                           double azimuth_deg, double elevation_deg) {
  const double az = DegToRad(azimuth_deg), el = DegToRad(elevation_deg);
  return ProjectEnu(cam_from_enu, k, {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)});
}

Eigen::Vector3d UnprojectToEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                               const Eigen::Vector2d& pixel) {
  const Eigen::Vector3d c((pixel.x() - k.cx) / k.focal_px, (pixel.y() - k.cy) / k.focal_px, 1.0);
  return (cam_from_enu.transpose() * c).normalized();
}

}  // namespace horizonreg
