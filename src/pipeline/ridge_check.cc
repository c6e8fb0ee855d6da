// SPDX-License-Identifier: MIT
#include "pipeline/ridge_check.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

namespace {
// At 1000 columns; pixels scale with the width.
constexpr double kSmoothPx = 1.0;           // Gaussian sigma of the grey image
constexpr int kLocalBoxPx = 15;             // the local mean gradient's square
constexpr double kBelowHorizonPx = 4.0;     // ridge points this near the skyline read the skyline's own edge
constexpr double kSearchPx = 3.0;           // across the line: the DEM's and the projection's error
constexpr double kMaxLinkPx = 20.0;         // a longer step to the next bin's ridge is no line
constexpr float kAcrossOverAlong = 2.0f;    // an aligned edge: across the line at least twice along it
constexpr float kOverLocalMean = 1.5f;      // ... and standing out of the texture around it
constexpr double kLinkDistanceShare = 0.1;  // the same ridge in the next bin: its distance within 10%
}  // namespace

PhotoEdges ComputePhotoEdges(const cv::Mat& image) {
  if (image.empty()) throw InvalidArgument("ComputePhotoEdges: empty image");
  cv::Mat grey, f;
  if (image.channels() == 3)
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  else
    grey = image;
  grey.convertTo(f, CV_32F);
  const double scale = std::max(1.0, image.cols / 1000.0);
  cv::GaussianBlur(f, f, cv::Size(0, 0), kSmoothPx * scale);
  PhotoEdges e;
  cv::Sobel(f, e.gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(f, e.gy, CV_32F, 0, 1, 3, 0.125);
  cv::Mat mag;
  cv::magnitude(e.gx, e.gy, mag);
  const int box = static_cast<int>(std::lround(kLocalBoxPx * scale)) | 1;
  cv::blur(mag, e.local_mean, cv::Size(box, box));
  return e;
}

RidgeSupport MeasureRidgeSupport(const PhotoEdges& edges, const HorizonProfile& horizon,
                                 const std::vector<std::vector<Ridge>>& ridges, const CameraPose& pose,
                                 const CameraIntrinsics& k) {
  if (edges.width() != k.width || edges.height() != k.height)
    throw InvalidArgument("MeasureRidgeSupport: the edges are not of the camera's image size");
  RidgeSupport out;
  const int n = horizon.size();
  if (n == 0 || static_cast<int>(ridges.size()) != n || !(k.focal_px > 0.0)) return out;
  const Eigen::Matrix3d cam_from_enu = CamFromEnu(pose);
  const int w = k.width, h = k.height;
  const double scale = std::max(1.0, w / 1000.0);
  const double half_view_deg = RadToDeg(std::atan(0.5 * w / k.focal_px)) + 2.0;
  const int reach = static_cast<int>(std::lround(kSearchPx * scale));
  for (int i = 0; i < n; ++i) {
    const double az = horizon.AzimuthDeg(i);
    if (ridges[i].empty() || std::abs(AngDiffDeg(az, pose.azimuth_deg)) > half_view_deg) continue;
    const int next_bin = (i + 1) % n;
    const auto sky = std::isfinite(horizon.elevation_deg[i])
                         ? ProjectAzEl(cam_from_enu, k, az, horizon.elevation_deg[i])
                         : std::optional<Eigen::Vector2d>();
    for (const Ridge& r : ridges[i]) {
      const auto p = ProjectAzEl(cam_from_enu, k, az, r.elevation_deg);
      if (!p || p->x() < reach + 1 || p->y() < reach + 1 || p->x() > w - reach - 2 || p->y() > h - reach - 2) continue;
      if (sky && p->y() < sky->y() + kBelowHorizonPx * scale) continue;
      const Ridge* next = nullptr;
      for (const Ridge& q : ridges[next_bin])
        if (std::abs(q.distance_m - r.distance_m) < kLinkDistanceShare * r.distance_m &&
            (!next || std::abs(q.distance_m - r.distance_m) < std::abs(next->distance_m - r.distance_m)))
          next = &q;
      if (!next) continue;
      const auto q = ProjectAzEl(cam_from_enu, k, horizon.AzimuthDeg(next_bin), next->elevation_deg);
      if (!q) continue;
      Eigen::Vector2d along = *q - *p;
      if (!(along.norm() > 1e-6) || along.norm() > kMaxLinkPx * scale) continue;
      along.normalize();
      const Eigen::Vector2d across(-along.y(), along.x());
      ++out.points;
      bool on_edge = false;
      for (int s = -reach; s <= reach && !on_edge; ++s) {
        const Eigen::Vector2d at = *p + static_cast<double>(s) * across;
        const int x = static_cast<int>(at.x()), y = static_cast<int>(at.y());  // the pixel holding `at`
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        const double gx = edges.gx.at<float>(y, x), gy = edges.gy.at<float>(y, x);
        const auto g_across = static_cast<float>(std::abs(gx * across.x() + gy * across.y()));
        const auto g_along = static_cast<float>(std::abs(gx * along.x() + gy * along.y()));
        on_edge = g_across >= kAcrossOverAlong * g_along &&
                  g_across >= kOverLocalMean * std::max(0.5f, edges.local_mean.at<float>(y, x));
      }
      out.supported += on_edge;
    }
  }
  return out;
}

std::vector<CameraPose> RidgeCheck::RuledOut() const {
  std::vector<CameraPose> out;
  for (const Rival& r : rivals)
    if (r.ruled_out) out.push_back(r.candidate.pose);
  return out;
}

bool RidgesRuleOut(const RidgeSupport& best, const RidgeSupport& rival) {
  if (best.points < kRidgeMinPoints || rival.points < kRidgeMinPoints) return false;
  const double b = best.Share(), r = rival.Share();
  return (b >= kRidgeMinBestShare && b >= kRidgeMinShareRatio * r) ||
         (b >= kRidgeMinBestShareClear && b >= kRidgeClearShareRatio * r);
}

RidgeCheck CheckRidges(const PhotoEdges& edges, const HorizonProfile& horizon,
                       const std::vector<std::vector<Ridge>>& ridges, const Registration& reg,
                       const RegistrationOptions& options) {
  RidgeCheck out;
  if (!(reg.focal_px > 0.0) || reg.candidates.empty()) return out;
  const int w = edges.width(), h = edges.height();
  const CameraIntrinsics k = reg.Intrinsics(w, h);
  out.best = MeasureRidgeSupport(edges, horizon, ridges, reg.pose, k);
  const double best_cost = reg.candidates.front().cost;
  for (const PoseCandidate& c : reg.candidates) {
    // The best solution itself, or one ruled out already (an earlier round's).
    if (RegistrationOptions::WithinRuledOutDeg(c.pose, reg.pose) || options.RulesOut(c.pose)) continue;
    if (!(c.cost < options.min_ambiguity_ratio * best_cost)) continue;  // no threat
    CameraIntrinsics kc = k;
    kc.focal_px = c.focal_px;
    RidgeCheck::Rival r{c, MeasureRidgeSupport(edges, horizon, ridges, c.pose, kc)};
    r.ruled_out = RidgesRuleOut(out.best, r.support);
    out.rivals.push_back(r);
  }
  return out;
}

}  // namespace horizonreg
