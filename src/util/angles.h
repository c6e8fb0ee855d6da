// SPDX-License-Identifier: MIT
// Angle helpers: the only place where degrees and radians are converted and
// where azimuths are wrapped (geo/conventions.h).
#pragma once

#include <cmath>
#include <numbers>

namespace horizonreg {

inline constexpr double kPi = std::numbers::pi;

constexpr double DegToRad(double deg) { return deg * (kPi / 180.0); }
constexpr double RadToDeg(double rad) { return rad * (180.0 / kPi); }

// Wraps an azimuth in degrees into [0, 360). NaN stays NaN.
inline double WrapAzimuthDeg(double azimuth_deg) {
  double a = std::fmod(azimuth_deg, 360.0);
  if (a < 0.0) a += 360.0;
  if (a >= 360.0) a -= 360.0;  // fmod(-1e-17) + 360 rounds to 360
  return a;
}

// Signed difference a - b of two azimuths in degrees, in [-180, 180).
inline double AngDiffDeg(double a_deg, double b_deg) {
  double d = WrapAzimuthDeg(a_deg - b_deg);
  return d >= 180.0 ? d - 360.0 : d;
}

}  // namespace horizonreg
