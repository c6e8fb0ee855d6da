// SPDX-License-Identifier: MIT
// Peaks and dips of a silhouette (paper, section 3.2): local maxima and
// minima of a 1-D signal with a significance, so that noise is not a peak.
#pragma once

#include <span>
#include <vector>

namespace horizonreg {

struct Extremum {
  double position = 0.0;    // sample index, sub-sample (parabola through the three samples around the extremum)
  double value = 0.0;       // signal at the extremum (up positive)
  bool is_max = true;       // peak (true) or dip (false)
  double prominence = 0.0;  // topographic prominence, in signal units (> 0)
};

struct ExtremaOptions {
  double min_prominence = 0.0;  // Extrema less prominent than this are dropped, signal units, >= 0.
  int max_count = 0;            // Keep at most this many of each kind, most prominent first; 0 = all.
  void Check() const;           // Throws InvalidArgument naming the field.
};

// Local maxima and minima of `values` with their topographic prominence: for
// a peak, its height above the higher of the two lowest points that separate
// it from higher signal (or from the end of its run) on either side; for a
// dip the same upside down. NaN samples split the signal into runs; an
// extremum must lie strictly inside its run (a value at a run's end may
// continue beyond what is seen). `circular` joins the last sample to the
// first (a 360-degree horizon). Flat tops give one extremum at their middle.
// Returns peaks and dips sorted by position. O(n log n + n * k), k the
// typical distance to higher signal. Thread-safe.
std::vector<Extremum> FindExtrema(std::span<const double> values, bool circular, const ExtremaOptions& options);

}  // namespace horizonreg
