// SPDX-License-Identifier: MIT
#include "track/track.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>

#include "match/predicted.h"
#include "pipeline/register_photo.h"
#include "skyline/band.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

void TrackerOptions::Check() const {
  registration.Check();
  if (!(band_px > 0.0)) ThrowField("TrackerOptions::band_px", band_px, "band_px > 0");
  if (!(min_edge_contrast >= 0.0)) ThrowField("TrackerOptions::min_edge_contrast", min_edge_contrast, ">= 0");
  if (max_tracked_gap < 0) ThrowField("TrackerOptions::max_tracked_gap", max_tracked_gap, ">= 0");
  if (!(prior_compass_sigma_deg > 0.0)) ThrowField("TrackerOptions::prior_compass_sigma_deg", prior_compass_sigma_deg, "> 0");
  if (!(calibrated_sigma_floor_deg > 0.0)) ThrowField("TrackerOptions::calibrated_sigma_floor_deg", calibrated_sigma_floor_deg, "> 0");
}

const char* PoseSourceName(PoseSource s) {
  switch (s) {
    case PoseSource::kVision:
      return "vision";
    case PoseSource::kTracked:
      return "tracked";
    case PoseSource::kSensors:
      return "sensors";
    case PoseSource::kNone:
      break;
  }
  return "none";
}

Tracker::Tracker(const HorizonProfile& horizon, int width, int height, const TrackerOptions& options)
    : horizon_(horizon), width_(width), height_(height), options_(options) {
  options_.Check();
  if (width < 8 || height < 8) throw InvalidArgument("Tracker: frame size must be at least 8 x 8");
  if (options_.registration.known_intrinsics) {
    lens_ = options_.registration.known_intrinsics->Resized(width, height);
    focal_px_ = lens_->focal_px;
  }
}

std::optional<Registration> Tracker::TrackAround(const cv::Mat& frame, const CameraPose& predicted, double focal_px) {
  CameraIntrinsics k = CameraIntrinsics::FromHfov(width_, height_, 50.0);
  k.focal_px = focal_px;
  if (lens_) k = *lens_;
  const double scale = std::max(0.5, width_ / 1000.0);
  const Skyline s = BandSkyline(frame, PredictedSkyline(horizon_, predicted, k), options_.band_px * scale,
                                options_.min_edge_contrast);
  RegistrationOptions o = options_.registration;
  o.min_inlier_fraction = options_.tracking_min_inlier_fraction;
  o.known_intrinsics = lens_;
  Registration r = RefinePose(s, horizon_, predicted, k.focal_px, true, o);
  if (!r.registered) return std::nullopt;
  // A jump the band could not have produced means the fit slid elsewhere.
  const double hfov = k.HfovDeg();
  if (std::abs(AngDiffDeg(r.pose.azimuth_deg, predicted.azimuth_deg)) > 0.1 * hfov ||
      std::abs(r.pose.pitch_deg - predicted.pitch_deg) > 0.1 * hfov)
    return std::nullopt;
  return r;
}

std::optional<Registration> Tracker::Track(const cv::Mat& frame) {
  if (!last_visual_ || frames_since_visual_ > options_.max_tracked_gap) return std::nullopt;
  const int steps = frames_since_visual_ + 1;
  CameraPose predicted = last_visual_->pose;
  predicted.azimuth_deg = WrapAzimuthDeg(predicted.azimuth_deg + steps * velocity_.azimuth_deg);
  predicted.pitch_deg += steps * velocity_.pitch_deg;
  predicted.roll_deg += steps * velocity_.roll_deg;
  return TrackAround(frame, predicted, last_visual_->focal_px);
}

std::optional<FramePose> Tracker::TrackFrom(const cv::Mat& frame_in, int index, const FramePose& neighbour) {
  if (neighbour.source != PoseSource::kVision && neighbour.source != PoseSource::kTracked) return std::nullopt;
  const cv::Mat frame = AsBgr(frame_in);
  if (frame.type() != CV_8UC3 || frame.cols != width_ || frame.rows != height_) return std::nullopt;
  const auto r = TrackAround(frame, neighbour.pose, neighbour.focal_px);
  if (!r) return std::nullopt;
  FramePose p;
  p.frame = index;
  p.pose = r->pose;
  p.focal_px = r->focal_px;
  p.source = PoseSource::kTracked;
  p.rms_px = r->rms_px;
  p.note = "tracked backwards";
  return p;
}

std::optional<FramePose> Tracker::SensorPose(int index, const SensorReading& raw, double time_s) const {
  const SensorReading c = calibration_ ? calibration_->Apply(raw, time_s) : raw;
  if (!c.compass_deg || !c.pitch_deg) return std::nullopt;
  FramePose p;
  p.frame = index;
  p.pose = {*c.compass_deg, *c.pitch_deg, c.roll_deg.value_or(0.0)};
  p.focal_px = focal_px_.value_or(0.0);
  p.source = PoseSource::kSensors;
  if (!calibration_) p.note = "uncalibrated sensors";
  return p;
}

std::optional<Registration> Tracker::RegisterFull(const cv::Mat& frame, const std::optional<SensorReading>& prior) {
  RegistrationOptions o = options_.registration;
  o.known_intrinsics = lens_;  // the lens does not change during a video
  if (prior) {
    o.prior.compass_deg = prior->compass_deg;
    o.prior.pitch_deg = prior->pitch_deg;
    o.prior.roll_deg = prior->roll_deg;
    if (calibration_) {
      const double rms = calibration_->compass_rms_deg;
      o.prior.compass_sigma_deg = std::max(options_.calibrated_sigma_floor_deg, std::isfinite(rms) ? 3.0 * rms : 5.0);
      o.prior.inclinometer_sigma_deg = std::max(options_.calibrated_sigma_floor_deg, 1.0);
    } else {
      o.prior.compass_sigma_deg = options_.prior_compass_sigma_deg;
    }
  }
  SkylineOptions so;
  if (prior && prior->roll_deg) so.roll_hint_deg = std::clamp(*prior->roll_deg, -45.0, 45.0);
  const Skyline s = ExtractSkyline(frame, so);
  Registration r = RegisterImage(frame, s, horizon_, o);
  if (!r.registered) return std::nullopt;
  return r;
}

FramePose Tracker::Process(const cv::Mat& frame_in, int index, const std::optional<SensorReading>& raw, double time_s) {
  if (frame_in.cols != width_ || frame_in.rows != height_)
    throw InvalidArgument("Tracker: frame " + std::to_string(index) + " has a different size");
  const cv::Mat frame = AsBgr(frame_in);
  if (frame.type() != CV_8UC3) throw InvalidArgument("Tracker: frames must be 8-bit gray or BGR");
  const std::optional<SensorReading> calibrated =
      raw ? std::optional<SensorReading>(calibration_ ? calibration_->Apply(*raw, time_s) : *raw) : std::nullopt;

  FramePose out;
  out.frame = index;
  std::optional<Registration> r = Track(frame);
  PoseSource source = PoseSource::kTracked;
  std::string note;
  if (!r) {
    r = RegisterFull(frame, calibrated);
    source = PoseSource::kVision;
    if (!r) note = "vision failed";
  }
  if (r) {
    out.pose = r->pose;
    out.focal_px = r->focal_px;
    out.source = source;
    out.rms_px = r->rms_px;
    if (last_visual_ && frames_since_visual_ == 0) {
      const double damp = 0.8;
      velocity_ = {damp * AngDiffDeg(out.pose.azimuth_deg, last_visual_->pose.azimuth_deg),
                   damp * (out.pose.pitch_deg - last_visual_->pose.pitch_deg),
                   damp * (out.pose.roll_deg - last_visual_->pose.roll_deg)};
    } else {
      velocity_ = {};
    }
    if (!focal_px_) focal_px_ = out.focal_px;
    if (!lens_) lens_ = r->Intrinsics(width_, height_);
    last_visual_ = out;
    frames_since_visual_ = 0;
    if (raw) {
      calibrator_.Add(time_s, *raw, out.pose.azimuth_deg, out.pose.pitch_deg, out.pose.roll_deg);
      calibration_ = calibrator_.Estimate();
    }
  } else {
    ++frames_since_visual_;
    out.note = note;
    if (calibrated && calibrated->compass_deg && calibrated->pitch_deg) {
      out.pose = {*calibrated->compass_deg, *calibrated->pitch_deg, calibrated->roll_deg.value_or(0.0)};
      out.source = PoseSource::kSensors;
      if (!calibration_) out.note += " (uncalibrated sensors)";
    } else if (last_) {
      out.pose = last_->pose;
      out.source = last_->source;
      out.note += " (last pose carried over)";
    }
    out.focal_px = focal_px_.value_or(0.0);
  }
  if (out.source != PoseSource::kNone) last_ = out;
  return out;
}

}  // namespace horizonreg
