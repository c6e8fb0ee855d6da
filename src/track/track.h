// SPDX-License-Identifier: MIT
// Video: initial registration, then frame-to-frame tracking of the skyline
// near where the previous pose predicts it, re-registration when tracking
// degrades, and calibrated compass/inclinometer when vision fails (paper,
// section 4.5 and its "future work").
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/register.h"
#include "sensors/sensors.h"

namespace cv {
class Mat;
}

namespace horizonreg {

struct TrackerOptions {
  RegistrationOptions registration;  // for full registrations (priors are set per frame from the sensors)
  double band_px = 24.0;             // Half-height of the band searched around the predicted skyline, pixels per
                                     // 1000 px of width, > 0.
  double min_edge_contrast = 30.0;   // Sum over B, G, R of the mean step across the boundary, 0-765.
  int max_tracked_gap = 3;           // Frames without a visual pose after which tracking restarts from scratch.
  double tracking_min_inlier_fraction = 0.6;  // Tracking is anchored by continuity: a lower bar than registration's.
  double prior_compass_sigma_deg = 15.0;      // raw compass, before any calibration
  double calibrated_sigma_floor_deg = 1.0;    // calibrated sensors are trusted no better than this
  void Check() const;
};

enum class PoseSource { kVision, kTracked, kSensors, kNone };
const char* PoseSourceName(PoseSource s);  // "vision", "tracked", "sensors", "none"

struct FramePose {
  int frame = 0;
  CameraPose pose;
  double focal_px = 0.0;
  PoseSource source = PoseSource::kNone;
  double rms_px = NAN;  // of the visual fit (vision, tracked)
  std::string note;     // why vision was not used, when it was not
};

// Per-frame state machine. Keeps a reference to `horizon` (the caller keeps
// it alive; the observer does not move). Not thread-safe.
class Tracker {
 public:
  Tracker(const HorizonProfile& horizon, int width, int height, const TrackerOptions& options);

  // One frame (8-bit BGR/gray, the constructor's size), its raw sensor
  // reading if any, and its time in seconds. Always returns a pose when one
  // is possible: vision, else tracked, else calibrated (or raw) sensors, else
  // the last pose carried over (source kNone before any pose exists).
  FramePose Process(const cv::Mat& frame, int index, const std::optional<SensorReading>& raw_sensors, double time_s);

  // Backward filling of frames that came before the first visual pose: the
  // pose of `frame` tracked from a neighbouring frame's pose (no motion
  // model); nullopt when tracking fails.
  std::optional<FramePose> TrackFrom(const cv::Mat& frame, int index, const FramePose& neighbour);
  // The pose from a raw sensor reading with the current calibration
  // (source kSensors), or nullopt without compass and pitch.
  std::optional<FramePose> SensorPose(int index, const SensorReading& raw, double time_s) const;

  void SetCalibration(const SensorCalibration& c) { calibration_ = c; }
  // The camera: the known intrinsics given in the options, else the lens the
  // first visual registration fitted (focal length, k1), kept for the rest
  // of the video (a lens does not change); nullopt before that.
  const std::optional<CameraIntrinsics>& lens() const { return lens_; }
  const std::optional<SensorCalibration>& calibration() const { return calibration_; }

 private:
  std::optional<Registration> Track(const cv::Mat& frame);
  std::optional<Registration> TrackAround(const cv::Mat& frame, const CameraPose& predicted, double focal_px);
  std::optional<Registration> RegisterFull(const cv::Mat& frame, const std::optional<SensorReading>& prior);

  const HorizonProfile& horizon_;
  int width_, height_;
  TrackerOptions options_;
  std::optional<FramePose> last_visual_;
  CameraPose velocity_;  // per frame
  int frames_since_visual_ = 0;
  std::optional<double> focal_px_;
  std::optional<CameraIntrinsics> lens_;
  std::optional<FramePose> last_;
  SensorCalibrator calibrator_;
  std::optional<SensorCalibration> calibration_;
};

}  // namespace horizonreg
