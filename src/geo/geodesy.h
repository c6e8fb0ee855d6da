// SPDX-License-Identifier: MIT
// WGS84 geodetic <-> ECEF <-> local ENU, exact (geo/conventions.h).
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "geo/conventions.h"
#include "util/angles.h"

namespace horizonreg {

// A WGS84 position: latitude and longitude in degrees, height in metres
// above the ellipsoid (see conventions.h for how DEM heights are treated).
struct GeodeticPoint {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;
};

// Earth-centred earth-fixed coordinates of a geodetic point, in metres.
// Closed form, exact to rounding (< 1 nm). Valid for any latitude in
// [-90, 90] and any longitude. Thread-safe.
inline Eigen::Vector3d EcefFromGeodetic(const GeodeticPoint& p) {
  const double lat = DegToRad(p.lat_deg), lon = DegToRad(p.lon_deg);
  const double sin_lat = std::sin(lat), cos_lat = std::cos(lat);
  const double n = kWgs84A / std::sqrt(1.0 - kWgs84E2 * sin_lat * sin_lat);
  return {(n + p.height_m) * cos_lat * std::cos(lon), (n + p.height_m) * cos_lat * std::sin(lon),
          (n * (1.0 - kWgs84E2) + p.height_m) * sin_lat};
}

// Inverse of EcefFromGeodetic (GeographicLib::Geocentric, accurate to ~5 nm
// everywhere, including the poles and the earth's centre). Longitude is in
// [-180, 180]. Thread-safe.
GeodeticPoint GeodeticFromEcef(const Eigen::Vector3d& ecef_m);

// Refraction lift in metres of a target at ground distance `distance_m` for
// coefficient k (conventions.h): k d^2 / (2 R). k = 0 gives 0.
inline double RefractionLiftM(double distance_m, double k) {
  return k * distance_m * distance_m / (2.0 * kRefractionEarthRadiusM);
}

// The local east-north-up frame at an origin on the WGS84 ellipsoid.
// Immutable after construction; thread-safe.
class LocalFrame {
 public:
  // Throws InvalidArgument if the origin's latitude is outside [-90, 90],
  // its longitude outside [-540, 540] or any value is not finite.
  explicit LocalFrame(const GeodeticPoint& origin);

  const GeodeticPoint& origin() const { return origin_; }
  const Eigen::Vector3d& origin_ecef() const { return origin_ecef_; }
  // Rotation taking ECEF difference vectors into ENU (rows: east, north, up).
  const Eigen::Matrix3d& enu_from_ecef() const { return enu_from_ecef_; }

  Eigen::Vector3d EnuFromEcef(const Eigen::Vector3d& ecef_m) const { return enu_from_ecef_ * (ecef_m - origin_ecef_); }
  Eigen::Vector3d EnuFromGeodetic(const GeodeticPoint& p) const { return EnuFromEcef(EcefFromGeodetic(p)); }
  Eigen::Vector3d EcefFromEnu(const Eigen::Vector3d& enu_m) const {
    return origin_ecef_ + enu_from_ecef_.transpose() * enu_m;
  }
  GeodeticPoint GeodeticFromEnu(const Eigen::Vector3d& enu_m) const { return GeodeticFromEcef(EcefFromEnu(enu_m)); }

 private:
  GeodeticPoint origin_;
  Eigen::Vector3d origin_ecef_;
  Eigen::Matrix3d enu_from_ecef_;
};

// Azimuth (degrees, clockwise from north, [0, 360)) and elevation angle
// (degrees, up positive) of an ENU vector. The zero vector gives (0, 0).
struct AzEl {
  double azimuth_deg = 0.0;
  double elevation_deg = 0.0;
};
inline AzEl AzElFromEnu(const Eigen::Vector3d& enu) {
  return {WrapAzimuthDeg(RadToDeg(std::atan2(enu.x(), enu.y()))),
          RadToDeg(std::atan2(enu.z(), std::hypot(enu.x(), enu.y())))};
}

}  // namespace horizonreg
