// SPDX-License-Identifier: MIT
#include "match/predicted.h"

#include <cmath>
#include <optional>

#include "match/fit.h"
#include "match/fit_model.h"
#include "util/angles.h"

namespace horizonreg {

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

SkylineWindow ExpectedSkylineWindow(const HorizonProfile& horizon, const Registration& r,
                                    const RegistrationOptions& options, int width, int height) {
  SkylineWindow out;
  if (!(r.focal_px > 0.0)) return out;
  constexpr double kFlattenings = 4.0, kSigmas = 3.0;
  const CameraIntrinsics k = r.Intrinsics(width, height);
  out.predicted = PredictedSkyline(horizon, r.pose, k);
  out.above_px.assign(width, NAN);
  out.below_px.assign(width, NAN);
  const double scale = std::isfinite(r.dem.flattening_scale) ? r.dem.flattening_scale : 1.0;
  const match_detail::HorizonLookup lookup(horizon, match_detail::ScaledModel(options.dem_error, scale));
  const Eigen::Matrix3d m = CamFromEnu(r.pose);
  const double sigma = match_detail::SigmaPx(options, width);
  for (int x = 0; x < width; ++x) {
    const double y = out.predicted[x];
    if (!std::isfinite(y)) continue;
    const Eigen::Vector3d d = UnprojectToEnu(m, k, Eigen::Vector2d(x + 0.5, y));
    const double az = std::atan2(d.x(), d.y());
    const double noise = std::hypot(sigma, k.focal_px * lookup.PositionSigmaRad(az));
    out.below_px[x] = kSigmas * noise;
    out.above_px[x] = kSigmas * noise + kFlattenings * k.focal_px * lookup.FlatteningRad(az);
  }
  return out;
}

}  // namespace horizonreg
