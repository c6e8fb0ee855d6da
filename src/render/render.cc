// SPDX-License-Identifier: MIT
#include "render/render.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <opencv2/core.hpp>
#include <sstream>
#include <thread>

#include "util/angles.h"
#include "util/errors.h"
#include "util/fast_math.h"

namespace horizonreg {

void RenderOptions::Check() const {
  if (!(max_distance_m > 0.0 && std::isfinite(max_distance_m))) ThrowField("RenderOptions::max_distance_m", max_distance_m, "0 < d < inf");
  if (!(refraction >= -1.0 && refraction <= 1.0)) ThrowField("RenderOptions::refraction", refraction, "-1 <= k <= 1");
  if (!std::isfinite(sun_azimuth_deg)) ThrowField("RenderOptions::sun_azimuth_deg", sun_azimuth_deg, "finite");
  if (!(sun_elevation_deg > 0.0 && sun_elevation_deg <= 90.0))
    ThrowField("RenderOptions::sun_elevation_deg", sun_elevation_deg, "0 < elevation <= 90");
  if (!(haze_distance_m > 0.0)) ThrowField("RenderOptions::haze_distance_m", haze_distance_m, "haze_distance_m > 0");
}

namespace {

// One visible band of elevation angle in an azimuth column: tan(elevation)
// from lo to hi shows terrain at `distance_m` with colour bgr.
struct Span {
  float tan_lo, tan_hi;
  cv::Vec3b bgr;
};

struct Knot {
  double d;         // horizontal distance, m
  double lat, lon;  // ground point below
  double u0;        // ENU up of the ellipsoid point (height 0), m
};

class ColumnCaster {
 public:
  ColumnCaster(const TerrainWindow& terrain, const GeodeticPoint& observer, const RenderOptions& o)
      : terrain_(terrain), frame_(observer), o_(o) {
    // Height range of the window, for the colour ramp.
    lo_ = INFINITY, hi_ = -INFINITY;
    for (const DemGrid& g : terrain.grids)
      for (float h : g.height_m)
        if (std::isfinite(h)) lo_ = std::min<double>(lo_, h), hi_ = std::max<double>(hi_, h);
    if (!(hi_ > lo_)) hi_ = lo_ + 1.0;
    spacing_ = terrain.grids.empty() ? 30.0 : std::max(5.0, terrain.grids[0].SpacingM());
    const double sa = DegToRad(o.sun_azimuth_deg), se = DegToRad(o.sun_elevation_deg);
    sun_ = {std::sin(sa) * std::cos(se), std::cos(sa) * std::cos(se), std::sin(se)};
  }

  // The spans of the column at azimuth `az_rad`, ordered by elevation.
  std::vector<Span> Cast(double az_rad) const {
    const double se = std::sin(az_rad), ce = std::cos(az_rad);
    // Knots: exact WGS84 ground points along the ray, every ~1/40 of the range.
    std::vector<Knot> knots;
    const double first = 2.0;
    for (double d = first;; d = std::min(o_.max_distance_m, d * 1.25 + 200.0)) {
      const double drop = d * d / (2.0 * kRefractionEarthRadiusM);  // approximately on the ellipsoid
      const GeodeticPoint g = frame_.GeodeticFromEnu({d * se, d * ce, -frame_.origin().height_m - drop});
      const Eigen::Vector3d enu0 = frame_.EnuFromGeodetic({g.lat_deg, g.lon_deg, 0.0});
      knots.push_back({std::hypot(enu0.x(), enu0.y()), g.lat_deg, g.lon_deg, enu0.z()});
      if (d >= o_.max_distance_m) break;
    }
    std::vector<Span> spans;
    double max_tan = -INFINITY, prev_h = NAN, prev_d = 0.0;
    size_t k = 0;
    for (double d = first; d <= knots.back().d;) {
      while (k + 2 < knots.size() && knots[k + 1].d < d) ++k;
      const Knot &a = knots[k], &b = knots[k + 1];
      const double t = std::clamp((d - a.d) / (b.d - a.d), 0.0, 1.0);
      const double lat = a.lat + t * (b.lat - a.lat), lon = a.lon + t * (b.lon - a.lon);
      const auto h = terrain_.HeightAt(lat, lon);
      const double step = std::max(0.3 * spacing_, 0.0025 * d);
      if (h) {
        const double u = a.u0 + t * (b.u0 - a.u0) + *h + RefractionLiftM(d, o_.refraction);
        const double tan_el = u / d;
        if (tan_el > max_tan) {
          spans.push_back({static_cast<float>(spans.empty() ? -1e9 : max_tan), static_cast<float>(tan_el),
                           Shade(*h, Normal(lat, lon, (*h - prev_h) / std::max(1.0, d - prev_d), se, ce), d)});
          max_tan = tan_el;
        }
        prev_h = *h;
        prev_d = d;
      } else {
        prev_h = NAN;
      }
      d += step;
    }
    return spans;
  }

  static cv::Vec3b Sky(double tan_el) {
    const double t = std::clamp(std::atan(std::max(0.0, tan_el)) / DegToRad(35.0), 0.0, 1.0);
    const double s = std::sqrt(t);
    return cv::Vec3b(cv::saturate_cast<uchar>(238 - 38 * s), cv::saturate_cast<uchar>(218 - 75 * s),
                     cv::saturate_cast<uchar>(196 - 120 * s));
  }

 private:
  // Surface normal (ENU) from central differences one post spacing apart;
  // the slope along the ray where a neighbour is missing.
  Eigen::Vector3d Normal(double lat, double lon, double ray_slope, double se, double ce) const {
    const double dlat = spacing_ / 111'320.0, dlon = dlat / std::max(0.01, std::cos(DegToRad(lat)));
    const auto n = terrain_.HeightAt(lat + dlat, lon), s = terrain_.HeightAt(lat - dlat, lon);
    const auto e = terrain_.HeightAt(lat, lon + dlon), w = terrain_.HeightAt(lat, lon - dlon);
    if (n && s && e && w)
      return Eigen::Vector3d(-(*e - *w) / (2 * spacing_), -(*n - *s) / (2 * spacing_), 1.0).normalized();
    const double slope = std::isfinite(ray_slope) ? ray_slope : 0.0;
    return Eigen::Vector3d(-slope * se, -slope * ce, 1.0).normalized();
  }

  cv::Vec3b Shade(double h, const Eigen::Vector3d& n, double d) const {
    // Colour by height: meadow green, scrub, rock grey, snow at the top.
    const double t = (h - lo_) / (hi_ - lo_);
    cv::Vec3d base;
    if (t < 0.45)
      base = cv::Vec3d(70, 125, 85) * (1 - t / 0.45) + cv::Vec3d(80, 120, 120) * (t / 0.45);
    else if (t < 0.85)
      base = cv::Vec3d(80, 120, 120) * (1 - (t - 0.45) / 0.4) + cv::Vec3d(125, 130, 135) * ((t - 0.45) / 0.4);
    else
      base = cv::Vec3d(125, 130, 135) * (1 - (t - 0.85) / 0.15) + cv::Vec3d(235, 235, 235) * ((t - 0.85) / 0.15);
    // Lambert shading plus sky light.
    const double light = 0.35 + 0.85 * std::max(0.0, n.dot(sun_));
    const double haze = 1.0 - std::exp(-d / o_.haze_distance_m);
    const cv::Vec3d haze_colour(215, 200, 185);
    cv::Vec3b out;
    for (int c = 0; c < 3; ++c) out[c] = cv::saturate_cast<uchar>(base[c] * light * (1 - haze) + haze_colour[c] * haze);
    return out;
  }

  const TerrainWindow& terrain_;
  LocalFrame frame_;
  RenderOptions o_;
  double lo_, hi_, spacing_;
  Eigen::Vector3d sun_;
};

// Spans for columns az0 + i * step, i < n (two threads).
std::vector<std::vector<Span>> CastColumns(const ColumnCaster& caster, double az0_rad, double step_rad, int n) {
  std::vector<std::vector<Span>> columns(n);
  auto work = [&](int begin, int stride) {
    for (int i = begin; i < n; i += stride) columns[i] = caster.Cast(az0_rad + i * step_rad);
  };
  std::thread other(work, 1, 2);
  work(0, 2);
  other.join();
  return columns;
}

cv::Vec3b Lookup(const std::vector<Span>& spans, double tan_el, bool flat_sky) {
  if (spans.empty() || tan_el >= spans.back().tan_hi)
    return flat_sky ? cv::Vec3b(255, 0, 255) : ColumnCaster::Sky(tan_el);
  const auto it =
      std::upper_bound(spans.begin(), spans.end(), tan_el, [](double v, const Span& s) { return v < s.tan_hi; });
  return it->bgr;
}

}  // namespace

cv::Mat RenderView(const TerrainWindow& terrain, const GeodeticPoint& observer, const CameraPose& pose,
                   const CameraIntrinsics& k, const RenderOptions& options) {
  options.Check();
  k.Check();
  const Eigen::Matrix3d m = CamFromEnu(pose);
  // Azimuth range seen: the border pixels' azimuths relative to the axis.
  double lo = 0.0, hi = 0.0;
  bool full = false;
  auto visit = [&](double x, double y) {
    const AzEl ae = AzElFromEnu(UnprojectToEnu(m, k, {x, y}));
    const double rel = AngDiffDeg(ae.azimuth_deg, pose.azimuth_deg);
    if (std::abs(rel) > 170.0) full = true;
    lo = std::min(lo, rel), hi = std::max(hi, rel);
  };
  for (int i = 0; i <= 64; ++i) {
    visit(k.width * i / 64.0, 0.0), visit(k.width * i / 64.0, k.height);
    visit(0.0, k.height * i / 64.0), visit(k.width, k.height * i / 64.0);
  }
  if (full) lo = -180.0, hi = 180.0;
  const double step = std::min(0.05, 0.5 * RadToDeg(1.0 / k.focal_px));
  const double az0 = pose.azimuth_deg + lo - 2 * step;
  const int n = static_cast<int>(std::ceil((hi - lo) / step)) + 5;
  const ColumnCaster caster(terrain, observer, options);
  const auto columns = CastColumns(caster, DegToRad(az0), DegToRad(step), n);
  cv::Mat out(k.height, k.width, CV_8UC3);
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const Eigen::Vector3d d = UnprojectToEnu(m, k, {c + 0.5, r + 0.5});
      const double h = std::hypot(d.x(), d.y());
      const double az = RadToDeg(FastAtan2(d.x(), d.y()));
      double rel = WrapAzimuthDeg(az - az0);
      if (rel >= 360.0 - 4.0 * step) rel = 0.0;  // just left of the first column
      const int i = std::clamp(static_cast<int>(std::lround(rel / step)), 0, n - 1);
      out.at<cv::Vec3b>(r, c) = Lookup(columns[i], h > 1e-12 ? d.z() / h : (d.z() > 0 ? 1e9 : -1e9), options.flat_sky);
    }
  return out;
}

cv::Mat RenderPanorama(const TerrainWindow& terrain, const GeodeticPoint& observer, int width_px, int height_px,
                       double min_elevation_deg, double max_elevation_deg, const RenderOptions& options) {
  options.Check();
  if (width_px < 8 || height_px < 8) throw InvalidArgument("RenderPanorama: size must be at least 8 x 8");
  if (!(min_elevation_deg < max_elevation_deg && min_elevation_deg > -90.0 && max_elevation_deg < 90.0))
    throw InvalidArgument("RenderPanorama: need -90 < min_elevation_deg < max_elevation_deg < 90");
  const ColumnCaster caster(terrain, observer, options);
  const double step = 360.0 / width_px;
  const auto columns = CastColumns(caster, DegToRad(0.5 * step), DegToRad(step), width_px);
  cv::Mat out(height_px, width_px, CV_8UC3);
  for (int r = 0; r < height_px; ++r) {
    const double el = max_elevation_deg - (r + 0.5) * (max_elevation_deg - min_elevation_deg) / height_px;
    const double t = std::tan(DegToRad(el));
    for (int c = 0; c < width_px; ++c) out.at<cv::Vec3b>(r, c) = Lookup(columns[c], t, options.flat_sky);
  }
  return out;
}

}  // namespace horizonreg
