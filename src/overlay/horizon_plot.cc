// SPDX-License-Identifier: MIT
#include "overlay/horizon_plot.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "util/errors.h"

namespace horizonreg {
namespace {

// Distance colour ramp: near = dark green-brown, far = pale blue-grey (aerial perspective).
cv::Scalar DistanceColour(double distance_m, double max_m) {
  const double t = std::clamp(std::log1p(distance_m / 1000.0) / std::log1p(max_m / 1000.0), 0.0, 1.0);
  const cv::Vec3d near(40, 80, 60), far(200, 175, 150);  // BGR
  const cv::Vec3d c = near * (1 - t) + far * t;
  return {c[0], c[1], c[2]};
}

std::string Format(double v, int precision) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

}  // namespace

void HorizonPlotOptions::Check() const {
  if (width_px < 400 || width_px > 20000) throw InvalidArgument("HorizonPlotOptions::width_px must be in 400..20000");
  if (height_px < 200 || height_px > 20000)
    throw InvalidArgument("HorizonPlotOptions::height_px must be in 200..20000");
}

cv::Mat PlotHorizon(const HorizonProfile& profile, const std::vector<std::vector<Ridge>>& ridges,
                    const HorizonPlotOptions& options) {
  options.Check();
  const int w = options.width_px, h = options.height_px;
  const int left = 70, right = 20, top = 50, bottom = 60;
  const int pw = w - left - right, ph = h - top - bottom;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));

  double lo = INFINITY, hi = -INFINITY, dmax = 1000.0;
  for (int i = 0; i < profile.size(); ++i) {
    if (!std::isfinite(profile.elevation_deg[i])) continue;
    lo = std::min(lo, profile.elevation_deg[i]);
    hi = std::max(hi, profile.elevation_deg[i]);
    dmax = std::max(dmax, profile.distance_m[i]);
  }
  if (!std::isfinite(lo)) lo = -1.0, hi = 1.0;
  // Round the range to a readable tick step.
  const double span = std::max(hi - lo, 0.5);
  const double steps[] = {0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 30};
  double tick = 30;
  for (double s : steps)
    if (span / s <= 8) {
      tick = s;
      break;
    }
  lo = std::floor((lo - 0.1 * span) / tick) * tick;
  hi = std::ceil((hi + 0.15 * span) / tick) * tick;
  auto x_of = [&](double az) { return left + az / 360.0 * pw; };
  auto y_of = [&](double el) { return top + (hi - el) / (hi - lo) * ph; };

  // Sky gradient.
  for (int y = top; y < top + ph; ++y) {
    const double t = double(y - top) / ph;
    cv::line(img, {left, y}, {left + pw, y}, cv::Scalar(250 - 40 * (1 - t), 235 - 30 * (1 - t), 215 - 60 * (1 - t)));
  }
  // Terrain columns, coloured by the distance of the horizon point.
  const int n = profile.size();
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(profile.elevation_deg[i])) continue;
    const double az0 = profile.AzimuthDeg(i) - profile.azimuth_step_deg / 2;
    const double az1 = az0 + profile.azimuth_step_deg;
    const cv::Scalar col = DistanceColour(profile.distance_m[i], dmax);
    for (double shift : {0.0, 360.0, -360.0}) {
      const int x0 = static_cast<int>(std::floor(x_of(az0 + shift))),
                x1 = static_cast<int>(std::ceil(x_of(az1 + shift)));
      if (x1 < left || x0 > left + pw) continue;
      const int y0 = static_cast<int>(std::round(y_of(profile.elevation_deg[i])));
      cv::rectangle(img, cv::Point(std::max(x0, left), std::max(y0, top)), cv::Point(std::min(x1, left + pw), top + ph),
                    col, cv::FILLED);
    }
  }
  // Inner ridge lines.
  for (int i = 0; i < static_cast<int>(ridges.size()) && i < n; ++i) {
    for (const Ridge& r : ridges[i]) {
      if (r.elevation_deg < lo || r.elevation_deg > hi) continue;  // outside the chart
      const cv::Point p(static_cast<int>(x_of(profile.AzimuthDeg(i))), static_cast<int>(y_of(r.elevation_deg)));
      cv::circle(img, p, 1, DistanceColour(r.distance_m, dmax) * 0.55, cv::FILLED);
    }
  }
  // Horizon line.
  std::vector<cv::Point> line;
  for (int i = 0; i <= n; ++i) {
    const int k = i % n;
    if (!std::isfinite(profile.elevation_deg[k])) {
      if (line.size() > 1) cv::polylines(img, line, false, cv::Scalar(20, 20, 20), 1, cv::LINE_AA);
      line.clear();
      continue;
    }
    line.emplace_back(static_cast<int>(std::round(x_of(i * profile.azimuth_step_deg))),
                      static_cast<int>(std::round(y_of(profile.elevation_deg[k]))));
  }
  if (line.size() > 1) cv::polylines(img, line, false, cv::Scalar(20, 20, 20), 1, cv::LINE_AA);

  // Grid, axes, labels.
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(40, 40, 40), grid(150, 150, 150);
  for (double el = lo; el <= hi + 1e-9; el += tick) {
    const int y = static_cast<int>(std::round(y_of(el)));
    cv::line(img, {left, y}, {left + pw, y}, grid, 1, std::abs(el) < 1e-9 ? cv::LINE_8 : cv::LINE_4);
    const std::string label = Format(el, tick < 1 ? 1 : 0);
    int base;
    const cv::Size sz = cv::getTextSize(label, font, 0.45, 1, &base);
    cv::putText(img, label, {left - 8 - sz.width, y + sz.height / 2}, font, 0.45, ink, 1, cv::LINE_AA);
  }
  if (lo < 0 && hi > 0) {
    const int y0 = static_cast<int>(std::round(y_of(0)));
    cv::line(img, {left, y0}, {left + pw, y0}, cv::Scalar(0, 0, 200), 1, cv::LINE_AA);
  }
  const char* names[] = {"N", "NE", "E", "SE", "S", "SW", "W", "NW", "N"};
  for (int k = 0; k <= 36; ++k) {
    const double az = k * 10.0;
    const int x = static_cast<int>(std::round(x_of(az)));
    const bool major = static_cast<int>(az) % 45 == 0;
    cv::line(img, {x, top + ph}, {x, top + ph + (major ? 10 : 5)}, ink, 1);
    if (static_cast<int>(az) % 45 == 0) {
      cv::line(img, {x, top}, {x, top + ph}, cv::Scalar(120, 120, 120), 1, cv::LINE_4);
      const std::string name = names[static_cast<int>(az) / 45];
      int base;
      const cv::Size sz = cv::getTextSize(name, font, 0.7, 2, &base);
      cv::putText(img, name, {x - sz.width / 2, top + ph + 30}, font, 0.7, ink, 2, cv::LINE_AA);
      const std::string deg = Format(az, 0);
      const cv::Size sd = cv::getTextSize(deg, font, 0.4, 1, &base);
      cv::putText(img, deg, {x - sd.width / 2, top + ph + 48}, font, 0.4, ink, 1, cv::LINE_AA);
    } else if (k % 3 == 0) {
      const std::string deg = Format(az, 0);
      int base;
      const cv::Size sd = cv::getTextSize(deg, font, 0.4, 1, &base);
      cv::putText(img, deg, {x - sd.width / 2, top + ph + 48}, font, 0.4, ink, 1, cv::LINE_AA);
    }
  }
  cv::rectangle(img, cv::Point(left, top), cv::Point(left + pw, top + ph), ink, 1);
  cv::putText(img, "elevation angle (deg)", {8, top - 6}, font, 0.45, ink, 1, cv::LINE_AA);
  cv::putText(img, options.title, {left, 22}, font, 0.65, ink, 1, cv::LINE_AA);
  // Distance legend.
  const int lx = left + pw - 300, ly = 18;
  for (int i = 0; i < 200; ++i) {
    const double d = std::expm1(i / 199.0 * std::log1p(dmax / 1000.0)) * 1000.0;
    cv::line(img, {lx + i, ly}, {lx + i, ly + 12}, DistanceColour(d, dmax));
  }
  cv::putText(img, "near", {lx - 40, ly + 11}, font, 0.4, ink, 1, cv::LINE_AA);
  cv::putText(img, Format(dmax / 1000.0, 0) + " km", {lx + 205, ly + 11}, font, 0.4, ink, 1, cv::LINE_AA);

  return img;
}

}  // namespace horizonreg
