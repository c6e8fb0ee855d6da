// SPDX-License-Identifier: MIT
#include "overlay/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

void OverlayOptions::Check() const {
  if (!(eye_height_m > 0.0 && std::isfinite(eye_height_m))) {
    std::ostringstream m;
    m << "OverlayOptions::eye_height_m = " << eye_height_m << "; violated: eye_height_m > 0";
    throw InvalidArgument(m.str());
  }
}

namespace {

constexpr int kShift = 4;  // sub-pixel drawing
cv::Point Fixed(const Eigen::Vector2d& p) {
  return {static_cast<int>(std::lround(p.x() * (1 << kShift))), static_cast<int>(std::lround(p.y() * (1 << kShift)))};
}

// Near (red) to far (blue) over log distance 1-100 km.
cv::Scalar DistanceColour(double distance_m) {
  const double t = std::clamp(std::log10(std::max(distance_m, 1.0) / 1000.0) / 2.0, 0.0, 1.0);
  return cv::Scalar(255 * t, 80 + 100 * (1 - std::abs(2 * t - 1)), 255 * (1 - t));
}

struct Canvas {
  cv::Mat img;
  double scale;  // 1 at 1000 px wide
  int thick;
  const Eigen::Matrix3d& m;
  const CameraIntrinsics& k;
  bool Inside(const Eigen::Vector2d& p, double margin) const {
    return p.x() > -margin && p.x() < k.width + margin && p.y() > -margin && p.y() < k.height + margin;
  }
  std::optional<Eigen::Vector2d> Project(double az, double el) const { return ProjectAzEl(m, k, az, el); }
  void Line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const cv::Scalar& c, int t) {
    cv::line(img, Fixed(a), Fixed(b), c, t, cv::LINE_AA, kShift);
  }
  // Text with a dark halo, legible on sky and terrain.
  void Text(const std::string& s, cv::Point org, double font, const cv::Scalar& colour) {
    const int t = std::max(1, static_cast<int>(std::lround(1.4 * scale)));
    cv::putText(img, s, org, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(20, 20, 20), t + 2 * std::max(1, t / 2 + 1),
                cv::LINE_AA);
    cv::putText(img, s, org, cv::FONT_HERSHEY_SIMPLEX, font, colour, t, cv::LINE_AA);
  }
  cv::Size TextSize(const std::string& s, double font) const {
    int base = 0;
    const int t = std::max(1, static_cast<int>(std::lround(1.4 * scale)));
    cv::Size sz = cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, font, t + 2, &base);
    sz.height += base;
    return sz;
  }
};

// A polyline of (azimuth, elevation) samples, broken where it leaves the view.
void DrawAngularPolyline(Canvas& cv_, const std::vector<std::pair<double, double>>& pts, const cv::Scalar& colour,
                         int thick) {
  std::optional<Eigen::Vector2d> prev;
  for (const auto& [az, el] : pts) {
    const auto p = cv_.Project(az, el);
    const bool ok = p && cv_.Inside(*p, 0.5 * cv_.k.width);
    if (ok && prev && (*p - *prev).norm() < 0.5 * cv_.k.width) cv_.Line(*prev, *p, colour, thick);
    prev = ok ? p : std::nullopt;
  }
}

// Azimuth range covered by the image (relative to the axis), degrees.
std::pair<double, double> AzimuthSpan(const Canvas& c, const CameraPose& pose) {
  double lo = 0, hi = 0;
  for (int i = 0; i <= 32; ++i)
    for (const Eigen::Vector2d& px :
         {Eigen::Vector2d(c.k.width * i / 32.0, 0), Eigen::Vector2d(c.k.width * i / 32.0, c.k.height),
          Eigen::Vector2d(0, c.k.height * i / 32.0), Eigen::Vector2d(c.k.width, c.k.height * i / 32.0)}) {
      const AzEl ae = AzElFromEnu(UnprojectToEnu(c.m, c.k, px));
      const double rel = AngDiffDeg(ae.azimuth_deg, pose.azimuth_deg);
      lo = std::min(lo, rel), hi = std::max(hi, rel);
    }
  return {lo - 1.0, hi + 1.0};
}

std::string CompassName(int az) {
  static const char* kNames[] = {"N", "NE", "E", "SE", "S", "SW", "W", "NW"};
  return kNames[((az % 360) / 45) % 8];
}

std::string Format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

}  // namespace

OverlayResult DrawOverlay(const cv::Mat& image, const CameraPose& pose, const CameraIntrinsics& k,
                          const OverlayInput& input, const OverlayOptions& o) {
  o.Check();
  k.Check();
  if (input.horizon == nullptr || input.horizon->size() == 0) throw InvalidArgument("DrawOverlay: no horizon profile");
  if (image.cols != k.width || image.rows != k.height)
    throw InvalidArgument("DrawOverlay: image size differs from the camera intrinsics");
  OverlayResult result;
  if (image.channels() == 1)
    cv::cvtColor(image, result.image, cv::COLOR_GRAY2BGR);
  else if (image.channels() == 4)
    cv::cvtColor(image, result.image, cv::COLOR_BGRA2BGR);
  else
    result.image = image.clone();
  const Eigen::Matrix3d m = CamFromEnu(pose);
  const double scale = std::max(0.6, k.width / 1000.0);
  Canvas c{result.image, scale, std::max(1, static_cast<int>(std::lround(2 * scale))), m, k};
  const HorizonProfile& h = *input.horizon;
  const auto [lo, hi] = AzimuthSpan(c, pose);
  const double font = 0.5 * scale;
  const int thin = std::max(1, static_cast<int>(std::lround(scale)));

  // Ground-plane grid: distance rings and radial lines on the plane eye_height below the eye.
  if (o.ground_grid) {
    const cv::Scalar grid(200, 230, 255);
    cv::Mat layer = result.image.clone();
    Canvas g{layer, scale, thin, m, k};
    auto ground = [&](double az_deg, double d) -> std::optional<Eigen::Vector2d> {
      const double a = DegToRad(az_deg);
      return ProjectEnu(m, k, {d * std::sin(a), d * std::cos(a), -o.eye_height_m});
    };
    for (double d : {5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0}) {
      std::optional<Eigen::Vector2d> prev;
      for (double a = lo; a <= hi; a += 0.5) {
        const auto p = ground(pose.azimuth_deg + a, d);
        const bool ok = p && g.Inside(*p, k.width);
        if (ok && prev) g.Line(*prev, *p, grid, thin);
        prev = ok ? p : std::nullopt;
      }
    }
    for (int a = static_cast<int>(std::ceil((pose.azimuth_deg + lo) / 10.0)) * 10; a <= pose.azimuth_deg + hi;
         a += 10) {
      std::optional<Eigen::Vector2d> prev;
      for (double d = 3.0; d <= 500.0; d *= 1.15) {
        const auto p = ground(a, d);
        const bool ok = p && g.Inside(*p, k.width);
        if (ok && prev) g.Line(*prev, *p, grid, thin);
        prev = ok ? p : std::nullopt;
      }
    }
    cv::addWeighted(layer, 0.45, result.image, 0.55, 0.0, result.image);
  }

  // Inner ridge lines: dots coloured by distance.
  if (o.ridges && input.ridges != nullptr && static_cast<int>(input.ridges->size()) == h.size()) {
    for (int i = 0; i < h.size(); ++i) {
      const double az = h.AzimuthDeg(i);
      if (std::abs(AngDiffDeg(az, pose.azimuth_deg)) > std::max(std::abs(lo), std::abs(hi))) continue;
      for (const Ridge& r : (*input.ridges)[i]) {
        const auto p = c.Project(az, r.elevation_deg);
        if (p && c.Inside(*p, 0))
          cv::circle(c.img, Fixed(*p), std::max(1, thin) << kShift, DistanceColour(r.distance_m), cv::FILLED,
                     cv::LINE_AA, kShift);
      }
    }
  }

  // DEM horizon, coloured by distance.
  if (o.horizon) {
    std::optional<Eigen::Vector2d> prev;
    for (int i = 0; i <= h.size(); ++i) {
      const int b = i % h.size();
      const double az = i * h.azimuth_step_deg;
      if (std::abs(AngDiffDeg(az, pose.azimuth_deg)) > std::max(std::abs(lo), std::abs(hi)) + 1.0) {
        prev.reset();
        continue;
      }
      const auto p = c.Project(az, h.elevation_deg[b]);
      const bool ok = p && c.Inside(*p, 0.5 * k.width);
      if (ok && prev && (*p - *prev).norm() < 0.5 * k.width)
        c.Line(*prev, *p, DistanceColour(h.distance_m[b]), c.thick);
      prev = ok ? p : std::nullopt;
    }
  }

  std::vector<cv::Rect> occupied;
  const int tape_y = static_cast<int>(std::lround(0.045 * k.height + 18 * scale));
  // Artificial horizon (0 deg elevation) and the vertical axis through the image centre.
  if (o.artificial_horizon) {
    std::vector<std::pair<double, double>> pts;
    for (double a = lo; a <= hi; a += 0.25) pts.push_back({pose.azimuth_deg + a, 0.0});
    DrawAngularPolyline(c, pts, cv::Scalar(0, 255, 255), thin);
  }
  if (o.vertical_axis) {
    std::vector<std::pair<double, double>> pts;
    for (double e = -89.0; e <= 89.0; e += 0.5) pts.push_back({pose.azimuth_deg, e});
    DrawAngularPolyline(c, pts, cv::Scalar(0, 255, 255), thin);
    // Pitch ladder ticks every 5 deg along it.
    for (int e = -85; e <= 85; e += 5) {
      const auto p = c.Project(pose.azimuth_deg, e);
      if (!p || !c.Inside(*p, 0)) continue;
      const auto q = c.Project(pose.azimuth_deg + 0.5, e);
      if (!q) continue;
      const Eigen::Vector2d dir = (*q - *p).normalized() * (e % 10 == 0 ? 12.0 : 6.0) * scale;
      c.Line(*p - dir, *p + dir, cv::Scalar(0, 255, 255), thin);
      if (e % 10 == 0 && p->y() > tape_y + 20 * scale && p->y() < k.height - 40 * scale)
        c.Text(std::to_string(e),
               cv::Point(static_cast<int>(p->x() + 15 * scale), static_cast<int>(p->y() + 5 * scale)), 0.8 * font,
               cv::Scalar(0, 255, 255));
    }
  }

  // Compass tape: ticks along the top of the image at the elevation seen there.
  if (o.compass) {
    const AzEl top = AzElFromEnu(UnprojectToEnu(m, k, {k.width / 2.0, static_cast<double>(tape_y)}));
    const double span = hi - lo;
    const int minor = span > 90 ? 5 : (span > 30 ? 1 : 1);
    const int major = span > 90 ? 15 : (span > 30 ? 10 : 5);
    for (int a = static_cast<int>(std::floor(pose.azimuth_deg + lo)); a <= pose.azimuth_deg + hi; ++a) {
      if (a % minor != 0) continue;
      const int az = ((a % 360) + 360) % 360;
      const auto p = c.Project(az, top.elevation_deg);
      if (!p || p->x() < 0 || p->x() > k.width) continue;
      const double len = (az % major == 0 ? 14.0 : 6.0) * scale;
      c.Line({p->x(), tape_y - len}, {p->x(), static_cast<double>(tape_y)}, cv::Scalar(255, 255, 255), thin);
      if (az % major == 0 || az % 45 == 0) {
        const std::string label = az % 45 == 0 ? CompassName(az) : std::to_string(az);
        const cv::Size sz = c.TextSize(label, font);
        const cv::Point org(static_cast<int>(p->x() - sz.width / 2.0), static_cast<int>(tape_y - len - 4 * scale));
        c.Text(label, org, font, az % 45 == 0 ? cv::Scalar(80, 220, 255) : cv::Scalar(255, 255, 255));
        occupied.push_back(cv::Rect(org.x, org.y - sz.height, sz.width, sz.height + static_cast<int>(len)));
      }
    }
  }

  // Read-out box, bottom left.
  if (o.readout) {
    std::vector<std::string> lines = {Format("azimuth %.2f", pose.azimuth_deg) +
                                      Format("   pitch %.2f", pose.pitch_deg) + Format("   roll %.2f", pose.roll_deg) +
                                      Format("   hfov %.1f deg", k.HfovDeg())};
    if (!o.caption.empty()) lines.push_back(o.caption);
    int y = k.height - static_cast<int>(10 * scale);
    for (auto it = lines.rbegin(); it != lines.rend(); ++it) {
      const cv::Size sz = c.TextSize(*it, font);
      c.Text(*it, cv::Point(static_cast<int>(10 * scale), y), font, cv::Scalar(255, 255, 255));
      occupied.push_back(cv::Rect(static_cast<int>(10 * scale), y - sz.height, sz.width, sz.height));
      y -= sz.height + static_cast<int>(6 * scale);
    }
  }

  // Landmarks: marker on the summit, leader line up to a label in a free tier.
  if (o.landmarks) {
    struct Candidate {
      const ResolvedLandmark* l;
      Eigen::Vector2d p;
    };
    std::vector<Candidate> cands;
    for (const ResolvedLandmark& l : input.landmarks) {
      if (!l.visible) continue;
      const auto p = c.Project(l.azimuth_deg, l.elevation_deg);
      if (!p || !c.Inside(*p, -2.0)) continue;
      cands.push_back({&l, *p});
    }
    // Named first, then higher summits first.
    std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) {
      if (a.l->name.empty() != b.l->name.empty()) return !a.l->name.empty();
      return a.l->height_m > b.l->height_m;
    });
    for (const Candidate& cand : cands) {
      const ResolvedLandmark& l = *cand.l;
      const double ele = l.ele_m.value_or(l.height_m);
      std::string text =
          (l.name.empty() ? "" : l.name + "  ") + Format("%.0f m", ele) + Format("  %.1f km", l.distance_m / 1000.0);
      const cv::Size sz = c.TextSize(text, font);
      const int x0 = std::clamp(static_cast<int>(cand.p.x() - sz.width / 2.0), 2, std::max(2, k.width - sz.width - 2));
      std::optional<cv::Rect> placed;
      const int gap = static_cast<int>(8 * scale);
      for (int level = 0; level < 8 && !placed; ++level) {
        const int y1 = static_cast<int>(cand.p.y()) - gap - 2 * gap - level * (sz.height + gap);
        const cv::Rect r(x0, y1 - sz.height, sz.width, sz.height);
        if (r.y < tape_y + 2) break;
        const bool free = std::none_of(occupied.begin(), occupied.end(), [&](const cv::Rect& q) {
          return (r & cv::Rect(q.x - gap, q.y - gap / 2, q.width + 2 * gap, q.height + gap)).area() > 0;
        });
        if (free) placed = r;
      }
      if (!placed) continue;
      occupied.push_back(*placed);
      const cv::Point anchor(static_cast<int>(cand.p.x()), placed->y + placed->height + 2);
      cv::line(c.img, anchor, cv::Point(static_cast<int>(cand.p.x()), static_cast<int>(cand.p.y() - 4 * scale)),
               cv::Scalar(255, 255, 255), thin, cv::LINE_AA);
      cv::circle(c.img, Fixed(cand.p), static_cast<int>(std::lround(4 * scale)) << kShift, cv::Scalar(0, 0, 255),
                 cv::FILLED, cv::LINE_AA, kShift);
      c.Text(text, cv::Point(placed->x, placed->y + placed->height - static_cast<int>(3 * scale)), font,
             l.name.empty() ? cv::Scalar(220, 220, 220) : cv::Scalar(255, 255, 255));
      result.labels.push_back({text, cand.p.x(), cand.p.y()});
    }
  }
  return result;
}

cv::Mat DrawPanoramaLabels(const cv::Mat& panorama, double min_elevation_deg, double max_elevation_deg,
                           const std::vector<ResolvedLandmark>& landmarks) {
  if (!(max_elevation_deg > min_elevation_deg)) throw InvalidArgument("DrawPanoramaLabels: empty elevation range");
  cv::Mat out;
  if (panorama.channels() == 1)
    cv::cvtColor(panorama, out, cv::COLOR_GRAY2BGR);
  else
    out = panorama.clone();
  const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
  const CameraIntrinsics k = CameraIntrinsics::FromHfov(std::max(1, out.cols), std::max(1, out.rows), 90.0);
  const double scale = 1.6;
  Canvas c{out, scale, 2, identity, k};
  const double font = 0.5 * scale;
  const int w = out.cols, h = out.rows;
  for (int az = 0; az < 360; az += 15) {
    const int x = static_cast<int>(az * w / 360.0);
    cv::line(out, {x, 0}, {x, static_cast<int>(12 * scale)}, cv::Scalar(255, 255, 255), 2);
    c.Text(az % 45 == 0 ? CompassName(az) : std::to_string(az), {x + 4, static_cast<int>(30 * scale)}, font,
           az % 45 == 0 ? cv::Scalar(80, 220, 255) : cv::Scalar(255, 255, 255));
  }
  for (const ResolvedLandmark& l : landmarks) {
    if (!l.visible) continue;
    const int x = static_cast<int>(l.azimuth_deg * w / 360.0);
    const int y = static_cast<int>((max_elevation_deg - l.elevation_deg) / (max_elevation_deg - min_elevation_deg) * h);
    cv::circle(out, {x, y}, 4, cv::Scalar(0, 0, 255), cv::FILLED, cv::LINE_AA);
    c.Text(l.name.empty() ? Format("%.0f m", l.height_m) : l.name, {x + 6, y - 8}, 0.9 * font,
           cv::Scalar(255, 255, 255));
  }
  return out;
}

std::vector<std::string> WrapText(const std::string& text, double font_scale, int thickness, int max_width_px,
                                  int max_lines) {
  if (max_lines <= 0) throw InvalidArgument("WrapText: max_lines must be > 0");
  auto width = [&](const std::string& s) {
    int base = 0;
    return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, font_scale, thickness, &base).width;
  };
  std::vector<std::string> lines;
  std::istringstream words(text);
  std::string word, line;
  bool left_over = false;
  while (words >> word) {
    const std::string longer = line.empty() ? word : line + " " + word;
    if (line.empty() || width(longer) <= max_width_px) {
      line = longer;
      continue;
    }
    if (static_cast<int>(lines.size()) + 1 == max_lines) {
      left_over = true;
      break;
    }
    lines.push_back(line);
    line = word;
  }
  if (!line.empty()) lines.push_back(left_over ? line + " ..." : line);
  return lines;
}

}  // namespace horizonreg
