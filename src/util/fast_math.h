// SPDX-License-Identifier: MIT
// Fast approximations of libm functions for inner loops, with stated error.
#pragma once

#include <algorithm>
#include <cmath>

namespace horizonreg {

// atan2(y, x) in radians, |error| < 2e-7 rad: range reduction to |z| <=
// tan(pi/8) and the odd Taylor series to z^13 (remainder < z^15/15).
inline double FastAtan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double mx = std::max(ax, ay), mn = std::min(ax, ay);
  if (mx == 0.0) return 0.0;
  double a = mn / mx;
  double offset = 0.0;
  if (a > 0.41421356237309503) {
    a = (a - 1.0) / (a + 1.0);
    offset = 0.78539816339744831;
  }
  const double z2 = a * a;
  double r =
      a * (1.0 + z2 * (-1.0 / 3 + z2 * (1.0 / 5 + z2 * (-1.0 / 7 + z2 * (1.0 / 9 + z2 * (-1.0 / 11 + z2 / 13))))));
  r += offset;
  if (ay > ax) r = 1.5707963267948966 - r;
  if (x < 0.0) r = 3.141592653589793 - r;
  return y < 0.0 ? -r : r;
}

}  // namespace horizonreg
