// SPDX-License-Identifier: MIT
#include "track/track.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>

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

std::vector<double> PredictedSkyline(const HorizonProfile& horizon, const CameraPose& pose, const CameraIntrinsics& k) {
  std::vector<double> y(k.width, NAN);
  const Eigen::Matrix3d m = CamFromEnu(pose);
  const double half = RadToDeg(std::atan(0.75 * std::hypot(k.width, k.height) / k.focal_px)) + 1.0;
  const int n = horizon.size();
  const int span = static_cast<int>(std::ceil(half / horizon.azimuth_step_deg));
  const int centre = static_cast<int>(std::lround(pose.azimuth_deg / horizon.azimuth_step_deg));
  std::optional<Eigen::Vector2d> prev;
  for (int j = centre - span; j <= centre + span; ++j) {
    const int b = ((j % n) + n) % n;
    const auto p = ProjectAzEl(m, k, j * horizon.azimuth_step_deg, horizon.elevation_deg[b]);
    if (p && prev && p->x() > prev->x()) {
      const int c0 = std::max(0, static_cast<int>(std::ceil(prev->x() - 0.5)));
      const int c1 = std::min(k.width - 1, static_cast<int>(std::floor(p->x() - 0.5)));
      for (int c = c0; c <= c1; ++c) {
        const double t = (c + 0.5 - prev->x()) / (p->x() - prev->x());
        y[c] = prev->y() + t * (p->y() - prev->y());
      }
    }
    prev = p;
  }
  return y;
}

namespace {

// The boundary r in [lo, hi] (between rows r - 1 and r) with the highest
// score(r), and its y refined to sub-pixel by a parabola through its
// neighbours' scores. lo <= hi. `scores` is scratch space.
struct Step {
  int row;
  double y, score;
};
template <typename Score>
Step StrongestStep(int lo, int hi, Score score, std::vector<double>& scores) {
  scores.assign(hi - lo + 1, 0.0);
  int best = 0;
  for (int r = lo; r <= hi; ++r) {
    scores[r - lo] = score(r);
    if (scores[r - lo] > scores[best]) best = r - lo;
  }
  double y = lo + best;
  if (best > 0 && best + 1 < static_cast<int>(scores.size())) {
    const double a = scores[best - 1], b = scores[best], d = scores[best + 1], denom = a - 2 * b + d;
    if (denom < 0) y += std::clamp(0.5 * (a - d) / denom, -0.5, 0.5);
  }
  return {lo + best, y, scores[best]};
}

}  // namespace

Skyline BandSkyline(const cv::Mat& frame, const std::vector<double>& predicted_y, double band_px, double min_contrast) {
  HR_CHECK(frame.type() == CV_8UC3) << "BandSkyline needs 8-bit BGR";
  HR_CHECK(static_cast<int>(predicted_y.size()) == frame.cols) << "one prediction per column";
  Skyline s;
  s.width = frame.cols;
  s.height = frame.rows;
  s.y.assign(frame.cols, NAN);
  s.confidence.assign(frame.cols, 0.0);
  const int h = frame.rows;
  std::vector<int> sum;  // per row: B + G + R of this column
  std::vector<double> scores;
  for (int c = 0; c < frame.cols; ++c) {
    const double p = predicted_y[c];
    if (!std::isfinite(p)) continue;
    const int lo = std::max(3, static_cast<int>(std::floor(p - band_px)));
    const int hi = std::min(h - 3, static_cast<int>(std::ceil(p + band_px)));
    if (hi - lo < 3) continue;
    sum.resize(hi - lo + 6);
    for (int r = lo - 3; r < hi + 3; ++r) {
      const cv::Vec3b& v = frame.at<cv::Vec3b>(r, c);
      sum[r - lo + 3] = v[0] + v[1] + v[2];
    }
    const auto [row, y, contrast] = StrongestStep(
        lo, hi,
        [&](int r) {  // mean of the three rows above against the three below
          const int i = r - lo + 3;
          return std::abs((sum[i - 1] + sum[i - 2] + sum[i - 3]) / 3.0 - (sum[i] + sum[i + 1] + sum[i + 2]) / 3.0);
        },
        scores);
    if (contrast < min_contrast) continue;
    s.y[c] = y;
    s.confidence[c] = std::min(1.0, contrast / (4.0 * std::max(1.0, min_contrast)));
  }
  return s;
}

namespace {

// 8-bit grey frames as BGR; anything else is returned as it is.
cv::Mat AsBgr(const cv::Mat& frame) {
  if (frame.type() != CV_8UC1) return frame;
  const cv::Mat planes[3] = {frame, frame, frame};
  cv::Mat bgr;
  cv::merge(planes, 3, bgr);
  return bgr;
}

}  // namespace

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

std::optional<Registration> RecheckWithGuidedSkyline(const cv::Mat& image, const Skyline& skyline,
                                                     const HorizonProfile& horizon, const Registration& first,
                                                     const RegistrationOptions& options) {
  // A near miss, not a guess: at most 0.2 short of the inlier share needed.
  const double min_first_inliers = options.min_inlier_fraction - 0.2;
  constexpr double kMinStep = 15.0;  // BGR distance of the 3-row means across the step (sky noise ~3)
  constexpr double kMaxPoseMoveDeg = 0.2;
  // The columns to re-read inflate the best pose's misfit, so its ambiguity
  // ratio reads low; the search on the re-read skyline checks it again.
  const double min_first_ambiguity = 0.85 * options.min_ambiguity_ratio;
  const int w = skyline.width, h = skyline.height;
  const double px_scale = ToleranceScale(w), tau = options.inlier_px * px_scale;
  if (first.registered || !(first.focal_px > 0.0) || first.inlier_fraction < min_first_inliers ||
      !(first.model_rms_px <= options.max_rms_px * px_scale) || first.ambiguity_ratio < min_first_ambiguity)
    return std::nullopt;
  const cv::Mat bgr = AsBgr(image);
  if (bgr.type() != CV_8UC3 || bgr.cols != w || bgr.rows != h || static_cast<int>(skyline.y.size()) != w)
    return std::nullopt;
  const std::vector<double> pred = PredictedSkyline(horizon, first.pose, first.Intrinsics(w, h));
  auto mean3 = [&](int r0, int c) {  // mean BGR of rows r0 .. r0 + 2
    cv::Vec3d m(0, 0, 0);
    for (int r = r0; r < r0 + 3; ++r) m += cv::Vec3d(bgr.at<cv::Vec3b>(r, c));
    return m / 3.0;
  };
  Skyline guided = skyline;
  int reread = 0;
  std::vector<double> scores;
  for (int c = 0; c < w; ++c) {
    const double p = pred[c], y = skyline.y[c];
    if (!std::isfinite(p) || !std::isfinite(y) || y - p <= tau) continue;  // fits, lies above, or is hidden
    // Boundaries between rows r - 1 and r, above the extracted one.
    const int lo = std::max(6, static_cast<int>(std::floor(p - 2 * tau)));
    const int hi = std::min({h - 3, static_cast<int>(std::ceil(p + 2 * tau)), static_cast<int>(std::floor(y - tau))});
    if (hi < lo) continue;
    const auto [r, yr, contrast] = StrongestStep(
        lo, hi, [&](int row) { return cv::norm(mean3(row, c) - mean3(row - 3, c)); }, scores);
    if (contrast < kMinStep || cv::norm(mean3(r - 3, c) - mean3(r - 6, c)) > 0.5 * kMinStep) continue;
    guided.y[c] = yr;
    guided.confidence[c] = std::min(1.0, contrast / (4.0 * kMinStep));
    ++reread;
  }
  // A few columns would only give the refit a second chance at the same
  // skyline: the re-read must be a part of it that can carry the decision.
  if (reread < std::max(8, w / 32)) return std::nullopt;
  Registration r = RefinePose(guided, horizon, first.pose, first.focal_px, false, options);
  auto moved = [&](const CameraPose& p) {
    return std::abs(AngDiffDeg(p.azimuth_deg, first.pose.azimuth_deg)) > kMaxPoseMoveDeg ||
           std::abs(p.pitch_deg - first.pose.pitch_deg) > kMaxPoseMoveDeg;
  };
  std::ostringstream m;
  if (r.registered && moved(r.pose)) {
    r.registered = false;
    m << "the re-read skyline moved the pose; " << first.message;
  } else if (r.registered) {
    // The re-read skyline must register on its own, by the whole decision
    // (ambiguity and evidence included), at the same pose.
    const Registration search = Register(guided, horizon, options);
    if (!search.registered) {
      r.registered = false;
      m << "the re-read skyline does not register on its own (" << search.message << "); " << first.message;
    } else if (moved(search.pose)) {
      r.registered = false;
      m << "the re-read skyline registers elsewhere; " << first.message;
    } else {
      r = search;
      m << "registered (" << reread << " columns re-read near the DEM horizon)";
    }
  } else {
    m << r.message << " (after re-reading " << reread << " columns)";
  }
  r.message = m.str();
  return r;
}

Registration RegisterImage(const cv::Mat& image, const Skyline& skyline, const HorizonProfile& horizon,
                           const RegistrationOptions& options) {
  Registration r = Register(skyline, horizon, options);
  if (!r.registered)
    if (auto again = RecheckWithGuidedSkyline(image, skyline, horizon, r, options); again && again->registered)
      return *again;
  return r;
}

}  // namespace horizonreg
