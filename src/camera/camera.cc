// SPDX-License-Identifier: MIT
#include "camera/camera.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

LensDistortion::LensDistortion(const std::vector<double>& k, const std::vector<double>& p) {
  if (k.size() > 6) ThrowField("LensDistortion::k.size()", k.size(), "at most 6 radial coefficients (k1..k6)");
  if (p.size() > 2) ThrowField("LensDistortion::p.size()", p.size(), "at most 2 tangential coefficients (p1, p2)");
  for (size_t i = 0; i < k.size(); ++i) {
    if (!(std::abs(k[i]) <= 100.0)) ThrowField("LensDistortion::k[i]", k[i], "finite, |k| <= 100");
    k_[i] = k[i];
  }
  for (size_t i = 0; i < p.size(); ++i) {
    if (!(std::abs(p[i]) <= 100.0)) ThrowField("LensDistortion::p[i]", p[i], "finite, |p| <= 100");
    p_[i] = p[i];
  }
  identity_ = std::all_of(k_.begin(), k_.end(), [](double v) { return v == 0.0; }) && p_[0] == 0.0 && p_[1] == 0.0;
  if (identity_) return;
  // The radial map r -> r radial(r) must increase; find where it first stops
  // (sampled finely up to r = 4, ~76 deg off axis, which no lens in this
  // model reaches usefully), and keep a small margin inside.
  constexpr int kSamples = 4000;
  constexpr double kMaxR = 4.0;
  auto rd = [&](double r) {
    const double r2 = r * r;
    return r * (1.0 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[2]))) / (1.0 + r2 * (k_[3] + r2 * (k_[4] + r2 * k_[5])));
  };
  valid_radius_ = INFINITY;
  double prev = 0.0;
  for (int i = 1; i <= kSamples; ++i) {
    const double r = kMaxR * i / kSamples, v = rd(r);
    if (!(v > prev)) {
      valid_radius_ = 0.98 * kMaxR * (i - 1) / kSamples;
      break;
    }
    prev = v;
  }
}

LensDistortion LensDistortion::Radial(double k1, double k2, double k3) { return LensDistortion({k1, k2, k3}, {}); }

std::optional<Eigen::Vector2d> LensDistortion::Undistort(const Eigen::Vector2d& distorted) const {
  if (identity_) return distorted;
  Eigen::Vector2d u = distorted;
  // Fixed-point iterations (as OpenCV's undistortPoints), then Newton with
  // the analytic-by-differences Jacobian for full precision.
  for (int it = 0; it < 20; ++it) {
    const double r2 = u.squaredNorm();
    const double radial =
        (1.0 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[2]))) / (1.0 + r2 * (k_[3] + r2 * (k_[4] + r2 * k_[5])));
    if (!(std::abs(radial) > 1e-6)) return std::nullopt;
    const double tx = 2.0 * p_[0] * u.x() * u.y() + p_[1] * (r2 + 2.0 * u.x() * u.x());
    const double ty = p_[0] * (r2 + 2.0 * u.y() * u.y()) + 2.0 * p_[1] * u.x() * u.y();
    u = Eigen::Vector2d((distorted.x() - tx) / radial, (distorted.y() - ty) / radial);
    if (!u.allFinite()) return std::nullopt;
  }
  for (int it = 0; it < 4; ++it) {
    const Eigen::Vector2d f = Distort(u.x(), u.y()) - distorted;
    if (f.norm() < 1e-15) break;
    constexpr double h = 1e-7;
    Eigen::Matrix2d j;
    j.col(0) = (Distort(u.x() + h, u.y()) - Distort(u.x() - h, u.y())) / (2 * h);
    j.col(1) = (Distort(u.x(), u.y() + h) - Distort(u.x(), u.y() - h)) / (2 * h);
    if (!(std::abs(j.determinant()) > 1e-12)) return std::nullopt;
    u -= j.inverse() * f;
  }
  if (!u.allFinite() || u.norm() > valid_radius_ || (Distort(u.x(), u.y()) - distorted).norm() > 1e-9)
    return std::nullopt;
  return u;
}

double FocalFromHfovPx(double hfov_deg, double width_px) { return (width_px / 2.0) / std::tan(DegToRad(hfov_deg) / 2.0); }
double HfovFromFocalDeg(double focal_px, double width_px) { return RadToDeg(2.0 * std::atan((width_px / 2.0) / focal_px)); }

CameraIntrinsics CameraIntrinsics::FromHfov(int width, int height, double hfov_deg) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.focal_px = FocalFromHfovPx(hfov_deg, width);
  k.cx_px = width / 2.0;
  k.cy_px = height / 2.0;
  return k;
}

double CameraIntrinsics::HfovDeg() const { return HfovFromFocalDeg(focal_px, width); }

bool CameraIntrinsics::IsCentredPinhole() const {
  return distortion.IsIdentity() && aspect == 1.0 && cx_px == width / 2.0 && cy_px == height / 2.0;
}

std::optional<Eigen::Vector2d> CameraIntrinsics::NormalizedFromPixel(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d d((pixel.x() - cx_px) / focal_px, (pixel.y() - cy_px) / FocalYPx());
  return distortion.Undistort(d);
}

std::optional<Eigen::Vector2d> CameraIntrinsics::PixelFromNormalized(const Eigen::Vector2d& xy) const {
  if (!distortion.IsIdentity() && !(xy.norm() <= distortion.ValidRadius())) return std::nullopt;
  const Eigen::Vector2d d = distortion.Distort(xy.x(), xy.y());
  return Eigen::Vector2d(cx_px + focal_px * d.x(), cy_px + FocalYPx() * d.y());
}

CameraIntrinsics CameraIntrinsics::Resized(int new_width, int new_height) const {
  CameraIntrinsics k = *this;
  const double sx = static_cast<double>(new_width) / width, sy = static_cast<double>(new_height) / height;
  k.width = new_width;
  k.height = new_height;
  k.focal_px = focal_px * sx;
  k.aspect = aspect * sy / sx;
  k.cx_px = cx_px * sx;
  k.cy_px = cy_px * sy;
  return k;
}

void CameraIntrinsics::Check() const {
  if (width < 1) ThrowField("CameraIntrinsics::width", width, "width >= 1");
  if (height < 1) ThrowField("CameraIntrinsics::height", height, "height >= 1");
  if (!(focal_px > 0.0) || !std::isfinite(focal_px)) ThrowField("CameraIntrinsics::focal_px", focal_px, "0 < focal_px < inf");
  if (!(aspect > 0.1 && aspect < 10.0)) ThrowField("CameraIntrinsics::aspect", aspect, "0.1 < fy / fx < 10");
  if (!std::isfinite(cx_px)) ThrowField("CameraIntrinsics::cx_px", cx_px, "finite");
  if (!std::isfinite(cy_px)) ThrowField("CameraIntrinsics::cy_px", cy_px, "finite");
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

namespace {

// The rotation (in the camera frame) taking the centre ray onto the optical
// axis: the smallest one.
Eigen::Matrix3d AxisFromCenterRay(const CameraIntrinsics& k) {
  const Eigen::Vector2d centre(k.width / 2.0, k.height / 2.0);
  const Eigen::Vector2d xy = k.NormalizedFromPixel(centre).value_or(
      Eigen::Vector2d((centre.x() - k.cx_px) / k.focal_px, (centre.y() - k.cy_px) / k.FocalYPx()));
  const Eigen::Vector3d ray = Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized();
  return Eigen::Quaterniond::FromTwoVectors(ray, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

}  // namespace

CameraPose CenterRayPose(const CameraPose& pose, const CameraIntrinsics& k) {
  if (k.cx_px == k.width / 2.0 && k.cy_px == k.height / 2.0) return pose;
  return PoseFromCamFromEnu(AxisFromCenterRay(k) * CamFromEnu(pose));
}

CameraPose AxisPoseFromCenterRay(const CameraPose& center_ray, const CameraIntrinsics& k) {
  if (k.cx_px == k.width / 2.0 && k.cy_px == k.height / 2.0) return center_ray;
  return PoseFromCamFromEnu(AxisFromCenterRay(k).transpose() * CamFromEnu(center_ray));
}

std::optional<Eigen::Vector2d> ProjectEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                          const Eigen::Vector3d& dir_enu) {
  const Eigen::Vector3d c = cam_from_enu * dir_enu;
  if (!(c.z() > 1e-12 * c.norm())) return std::nullopt;
  return k.PixelFromNormalized({c.x() / c.z(), c.y() / c.z()});
}

std::optional<Eigen::Vector2d> ProjectAzEl(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                                           double azimuth_deg, double elevation_deg) {
  const double az = DegToRad(azimuth_deg), el = DegToRad(elevation_deg);
  return ProjectEnu(cam_from_enu, k, {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)});
}

Eigen::Vector3d UnprojectToEnu(const Eigen::Matrix3d& cam_from_enu, const CameraIntrinsics& k,
                               const Eigen::Vector2d& pixel) {
  const Eigen::Vector2d xy = k.NormalizedFromPixel(pixel).value_or(
      Eigen::Vector2d((pixel.x() - k.cx_px) / k.focal_px, (pixel.y() - k.cy_px) / k.FocalYPx()));
  return (cam_from_enu.transpose() * Eigen::Vector3d(xy.x(), xy.y(), 1.0)).normalized();
}

}  // namespace horizonreg
