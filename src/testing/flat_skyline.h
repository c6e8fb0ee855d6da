// SPDX-License-Identifier: MIT
// Tests: a skyline at one row in every column.
#pragma once

#include "skyline/skyline.h"

namespace horizonreg::testing {

// A w x h image's skyline at `row` in every column, confidence 1.
inline Skyline FlatSkyline(int w, int h, double row) {
  Skyline s;
  s.width = w, s.height = h;
  s.y.assign(w, row);
  s.confidence.assign(w, 1.0);
  return s;
}

}  // namespace horizonreg::testing
