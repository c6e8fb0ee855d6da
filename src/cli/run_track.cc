// SPDX-License-Identifier: MIT
// `horizonreg track`: poses for every frame of a video (registration, then
// frame-to-frame tracking, calibrated sensors when vision fails), the poses
// CSV and the overlay video.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "cli/commands.h"
#include "cli/output.h"
#include "pipeline/site.h"
#include "overlay/overlay.h"
#include "pipeline/camera_file.h"
#include "track/track.h"
#include "util/errors.h"

namespace horizonreg::cli {

namespace {

std::string Fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

}  // namespace

int RunTrack(const TrackArgs& a) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  if (!(a.fps > 0 && a.fps < 1000)) throw InvalidArgument("--fps must be in (0, 1000)");
  if (a.max_frames < 0) throw InvalidArgument("--max-frames must be >= 0");
  std::optional<SensorLog> log;
  if (!a.sensors.empty()) {
    log = ReadSensorLog(a.sensors);
    const size_t shown = std::min<size_t>(log->warnings.size(), 5);
    for (size_t i = 0; i < shown; ++i) std::cerr << "horizonreg: warning: " << log->warnings[i] << "\n";
    if (log->warnings.size() > shown)
      std::cerr << "horizonreg: warning: " << log->warnings.size() - shown << " more sensor rows skipped\n";
  }
  std::optional<SensorCalibration> start_calibration;
  if (!a.calibration_in.empty()) start_calibration = SensorCalibration::Load(a.calibration_in);

  // OpenCV's video backends and FFmpeg print their own warnings on stderr
  // (a file that is no video, a directory, a truncated stream): the user
  // gets this command's one line instead. An FFmpeg level the user set
  // (OPENCV_FFMPEG_LOGLEVEL) is kept.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", /*overwrite=*/0);  // AV_LOG_QUIET, read when the backend starts
  if (std::error_code ec; std::filesystem::is_directory(a.input, ec)) throw InvalidArgument("track: '" + a.input + "' is a directory, not a video");
  cv::VideoCapture cap;
  const bool is_index = !a.input.empty() && a.input.find_first_not_of("0123456789") == std::string::npos;
  try {
    if (is_index)
      cap.open(std::stoi(a.input));
    else if (a.input.find('%') != std::string::npos || std::filesystem::exists(a.input))
      cap.open(a.input);
  } catch (const cv::Exception&) {
    cap.release();
  }
  if (!cap.isOpened()) throw IoError("track: cannot open video '" + a.input + "'");
  const double cap_fps = cap.get(cv::CAP_PROP_FPS);
  const double fps = cap_fps > 0 && cap_fps < 1000 && a.input.find('%') == std::string::npos ? cap_fps : a.fps;
  const int total = static_cast<int>(cap.get(cv::CAP_PROP_FRAME_COUNT));
  cv::Mat frame;
  if (!cap.read(frame) || frame.empty()) throw IoError("track: '" + a.input + "' has no readable frame");

  SiteOptions so;
  so.agl_m = a.agl;
  so.alt_m = a.alt;
  ThreadPool pool(2);
  const Site site(a.dem, a.lat, a.lon, so, &pool);
  const HorizonProfile& horizon = site.horizon();
  TrackerOptions to;
  if (!a.camera.empty()) to.registration.known_intrinsics = ReadCameraFile(a.camera, frame.cols, frame.rows);
  Tracker tracker(horizon, frame.cols, frame.rows, to);
  if (start_calibration) tracker.SetCalibration(*start_calibration);

  cv::VideoWriter writer;
  std::string video_tmp;
  if (!a.output.empty()) {
    const std::filesystem::path out(a.output);
    const std::string ext = out.extension().string();
    video_tmp = (out.parent_path() / ("." + out.stem().string() + ".part" + ext)).string();
    const int fourcc =
        ext == ".avi" ? cv::VideoWriter::fourcc('M', 'J', 'P', 'G') : cv::VideoWriter::fourcc('m', 'p', '4', 'v');
    writer.open(video_tmp, fourcc, fps, frame.size());
    if (!writer.isOpened()) throw IoError("track: cannot write video '" + a.output + "' (use .mp4 or .avi)");
  }
  const bool progress = isatty(STDERR_FILENO) != 0;
  std::ostringstream csv;
  csv << "frame,azimuth_deg,pitch_deg,roll_deg,hfov_deg,source\n";
  int index = 0, counts[4] = {0, 0, 0, 0};
  const auto landmarks = SummitsFromHorizon(horizon);
  // Frames before the first visual pose wait (up to kMaxPending) until one
  // arrives, then are tracked backwards from it or given calibrated sensors.
  struct Pending {
    cv::Mat frame;
    int index;
    std::optional<SensorReading> raw;
    double time_s;
    FramePose pose;
  };
  constexpr size_t kMaxPending = 300;
  std::vector<Pending> pending;
  bool seen_visual = false;
  auto emit = [&](const cv::Mat& img, const FramePose& p) {
    ++counts[static_cast<int>(p.source)];
    const bool has_pose = p.source != PoseSource::kNone && (p.focal_px > 0 || tracker.lens());
    CameraIntrinsics k = CameraIntrinsics::FromHfov(img.cols, img.rows, 50.0);
    if (tracker.lens())
      k = *tracker.lens();
    else if (p.focal_px > 0)
      k.focal_px = p.focal_px;
    if (p.source != PoseSource::kNone) {
      csv << p.frame << "," << Fixed(p.pose.azimuth_deg, 4) << "," << Fixed(p.pose.pitch_deg, 4) << ","
          << Fixed(p.pose.roll_deg, 4) << "," << (has_pose ? Fixed(k.HfovDeg(), 3) : "") << ","
          << PoseSourceName(p.source) << "\n";
    } else {
      csv << p.frame << ",,,,," << PoseSourceName(p.source) << "\n";
    }
    if (writer.isOpened()) {
      if (has_pose) {
        OverlayOptions oo;
        oo.ground_grid = false;
        oo.ridges = false;
        oo.caption = std::string("frame ") + std::to_string(p.frame) + "  source: " + PoseSourceName(p.source) +
                     (p.note.empty() ? "" : "  (" + p.note + ")");
        writer.write(DrawOverlay(img, p.pose, k, {&horizon, nullptr, landmarks}, oo).image);
      } else {
        writer.write(img);
      }
    }
  };
  auto flush_pending = [&](const std::optional<FramePose>& anchor) {
    std::optional<FramePose> neighbour = anchor;
    for (auto it = pending.rbegin(); it != pending.rend(); ++it) {
      std::optional<FramePose> p = neighbour ? tracker.TrackFrom(it->frame, it->index, *neighbour) : std::nullopt;
      if (!p && it->raw) p = tracker.SensorPose(it->index, *it->raw, it->time_s);
      if (p) {
        if (p->focal_px <= 0 && anchor) p->focal_px = anchor->focal_px;
        it->pose = *p;
      }
      neighbour = p && p->source == PoseSource::kTracked ? p : std::nullopt;
    }
    for (const Pending& q : pending) emit(q.frame, q.pose);
    pending.clear();
  };
  try {
    do {
      if (frame.channels() == 4) cv::extractChannel(frame, frame, 0);  // unusual; keep one plane
      const auto raw = log ? log->ForFrame(index, fps) : std::nullopt;
      const FramePose p = tracker.Process(frame, index, raw, index / fps);
      const bool visual = p.source == PoseSource::kVision || p.source == PoseSource::kTracked;
      if (!seen_visual && !visual && pending.size() < kMaxPending) {
        pending.push_back({frame.clone(), index, raw, index / fps, p});
      } else {
        if (!seen_visual) flush_pending(visual ? std::optional<FramePose>(p) : std::nullopt);
        seen_visual = seen_visual || visual;
        emit(frame, p);
      }
      ++index;
      if (progress) {
        const int width = 30;
        const int done = total > 0 ? std::min(width, index * width / total) : 0;
        std::fprintf(stderr, "\r[%s%s] %d%s frames", std::string(done, '#').c_str(),
                     std::string(width - done, total > 0 ? '.' : ' ').c_str(), index,
                     total > 0 ? ("/" + std::to_string(total)).c_str() : "");
      }
      if (a.max_frames > 0 && index >= a.max_frames) break;
    } while (cap.read(frame) && !frame.empty());
    flush_pending(std::nullopt);
  } catch (...) {
    if (progress) std::fprintf(stderr, "\n");
    if (writer.isOpened()) writer.release();
    if (!video_tmp.empty()) std::filesystem::remove(video_tmp);
    throw;
  }
  if (progress) std::fprintf(stderr, "\n");
  if (writer.isOpened()) {
    writer.release();
    std::error_code ec;
    std::filesystem::rename(video_tmp, a.output, ec);
    if (ec) throw IoError("track: cannot write video '" + a.output + "': " + ec.message());
  }
  if (!a.poses.empty()) WriteOutput(a.poses, csv.str());
  if (!a.calibration_out.empty() && tracker.calibration()) tracker.calibration()->Save(a.calibration_out);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  std::fprintf(stderr,
               "horizonreg track: %d frames in %.0f ms (%.1f fps): vision %d, tracked %d, sensors %d, none %d\n", index,
               ms, index * 1000.0 / ms, counts[0], counts[1], counts[2], counts[3]);
  if (tracker.calibration())
    std::fprintf(stderr,
                 "  calibration: compass %+.2f deg %+.3f deg/s, pitch %+.2f deg, roll %+.2f deg (%d visual poses)\n",
                 tracker.calibration()->compass_offset_deg, tracker.calibration()->compass_drift_deg_per_s,
                 tracker.calibration()->pitch_offset_deg, tracker.calibration()->roll_offset_deg,
                 tracker.calibration()->samples);
  return 0;
}

}  // namespace horizonreg::cli
