// SPDX-License-Identifier: MIT
// The conventions every horizonreg interface follows (DESIGN.md).
//
// - Geodetic positions: WGS84, latitude and longitude in degrees.
// - Heights: metres. DEM heights are taken as given by the file (usually
//   orthometric, above the geoid); horizonreg treats the geoid undulation as
//   constant over the area of one horizon computation, i.e. it uses DEM heights
//   as ellipsoidal heights. The undulation varies by a few metres over 100 km,
//   which moves a horizon point by < 0.003 deg; a constant offset has no
//   measurable effect on angles.
// - Local frame: ENU (x east, y north, z up) at the observer, tangent to the
//   WGS84 ellipsoid, computed exactly through ECEF (no flat-earth shortcut).
// - Azimuth: degrees clockwise from true north, in [0, 360).
// - Elevation angle / pitch: degrees above the local horizontal plane, up positive.
// - Roll: about the optical axis, positive when the camera's right side goes down.
// - Image: x right, y down, origin at the top-left corner of the top-left pixel;
//   the centre of pixel (c, r) is (c + 0.5, r + 0.5).
// - Refraction: a target at ground distance d is lifted by k d^2 / (2 R),
//   R = kRefractionEarthRadiusM, k = 0.13 by default; k = 0 is pure geometry.
#pragma once

namespace horizonreg {

inline constexpr double kWgs84A = 6378137.0;                   // semi-major axis, m
inline constexpr double kWgs84F = 1.0 / 298.257223563;         // flattening
inline constexpr double kWgs84E2 = kWgs84F * (2.0 - kWgs84F);  // first eccentricity squared
inline constexpr double kRefractionEarthRadiusM = 6371000.0;   // R of the refraction lift
inline constexpr double kDefaultRefraction = 0.13;             // k, dimensionless
inline constexpr double kDefaultEyeHeightM = 1.7;              // eye above ground, m

}  // namespace horizonreg
