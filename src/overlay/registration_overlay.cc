// SPDX-License-Identifier: MIT
#include "overlay/registration_overlay.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "util/angles.h"

namespace horizonreg {

namespace {

cv::Mat ToBgr(const cv::Mat& image) {
  cv::Mat out;
  if (image.channels() == 1)
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  else if (image.channels() == 4)
    cv::cvtColor(image, out, cv::COLOR_BGRA2BGR);
  else
    out = image.clone();
  return out;
}

// Near (red) to far (blue) over log distance 1-100 km.
cv::Scalar DistanceColour(double distance_m) {
  const double t = std::clamp(std::log10(std::max(distance_m, 1.0) / 1000.0) / 2.0, 0.0, 1.0);
  return cv::Scalar(255 * t, 80 + 100 * (1 - std::abs(2 * t - 1)), 255 * (1 - t));
}

}  // namespace

cv::Mat DrawHorizonCheck(const cv::Mat& image, const HorizonProfile& horizon, const CameraPose& pose,
                         const CameraIntrinsics& k, const std::vector<double>& skyline_y,
                         const std::string& caption) {
  cv::Mat out = ToBgr(image);
  const double scale = std::max(1.0, out.cols / 1000.0);
  const int thick = std::max(1, static_cast<int>(std::lround(2 * scale)));
  constexpr int kShift = 4;  // sub-pixel drawing
  auto fixed = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x() * (1 << kShift))),
                     static_cast<int>(std::lround(p.y() * (1 << kShift))));
  };
  for (size_t x = 0; x + 1 < skyline_y.size(); ++x)
    if (std::isfinite(skyline_y[x]) && std::isfinite(skyline_y[x + 1]))
      cv::line(out, fixed({x + 0.5, skyline_y[x]}), fixed({x + 1.5, skyline_y[x + 1]}), cv::Scalar(255, 255, 255),
               std::max(1, thick / 2), cv::LINE_AA, kShift);
  const Eigen::Matrix3d m = CamFromEnu(pose);
  std::optional<Eigen::Vector2d> prev;
  const double margin = 0.2 * k.width;
  for (int i = 0; horizon.size() > 0 && i <= horizon.size(); ++i) {
    const int b = i % horizon.size();
    const auto p = ProjectAzEl(m, k, i * horizon.azimuth_step_deg, horizon.elevation_deg[b]);
    const bool inside = p && p->x() > -margin && p->x() < k.width + margin && p->y() > -k.height &&
                        p->y() < 2.0 * k.height;
    if (inside && prev && std::abs(p->x() - prev->x()) < 0.5 * k.width)
      cv::line(out, fixed(*prev), fixed(*p), DistanceColour(horizon.distance_m[b]), thick, cv::LINE_AA, kShift);
    prev = inside ? p : std::nullopt;
  }
  if (!caption.empty()) {
    const double font = 0.6 * scale;
    int base = 0;
    const cv::Size ts = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, font, thick, &base);
    cv::rectangle(out, {0, 0}, {std::min(out.cols, ts.width + 20), ts.height + base + 12}, cv::Scalar(0, 0, 0),
                  cv::FILLED);
    cv::putText(out, caption, {10, ts.height + 6}, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(255, 255, 255), thick,
                cv::LINE_AA);
  }
  return out;
}

}  // namespace horizonreg
