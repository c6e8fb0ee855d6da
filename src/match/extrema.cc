// SPDX-License-Identifier: MIT
#include "match/extrema.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "util/errors.h"

namespace horizonreg {

void ExtremaOptions::Check() const {
  if (!(min_prominence >= 0.0) || !std::isfinite(min_prominence))
    ThrowField("ExtremaOptions::min_prominence", min_prominence, "0 <= min_prominence < inf");
  if (max_count < 0) ThrowField("ExtremaOptions::max_count", max_count, "max_count >= 0");
}

namespace {

// Peaks of one signal (dips are found by negating it).
void FindPeaks(std::span<const double> v, bool circular, bool is_max, std::vector<Extremum>& out) {
  const int n = static_cast<int>(v.size());
  auto at = [&](int i) {
    if (circular) i = ((i % n) + n) % n;
    return (i < 0 || i >= n) ? NAN : (is_max ? v[i] : -v[i]);
  };
  for (int i = 0; i < n; ++i) {
    const double c = at(i);
    if (std::isnan(c)) continue;
    const double prev = at(i - 1);
    if (std::isnan(prev) || prev >= c) continue;  // not a rise into i (also: i starts a run)
    // Plateau: extend over equal samples.
    int j = i;
    while (j - i < n - 1 && at(j + 1) == c) ++j;
    const double next = at(j + 1);
    if (std::isnan(next) || next >= c) continue;  // ends in a rise or at the end of the run
    // Prominence: walk each way until higher signal, the run's end or half the circle.
    double side_min[2];
    for (int s = 0; s < 2; ++s) {
      const int dir = s == 0 ? -1 : 1;
      double lowest = c;
      const int start = s == 0 ? i : j;
      for (int k = 1; k < n; ++k) {
        const double w = at(start + dir * k);
        if (std::isnan(w) || w > c) break;
        lowest = std::min(lowest, w);
      }
      side_min[s] = lowest;
    }
    const double prominence = c - std::max(side_min[0], side_min[1]);
    if (!(prominence > 0.0)) continue;
    double pos = 0.5 * (i + j);
    if (i == j) {  // parabola through the three samples
      const double denom = prev - 2.0 * c + next;
      if (denom < 0.0) pos += std::clamp(0.5 * (prev - next) / denom, -0.5, 0.5);
    }
    if (circular) pos = std::fmod(pos + n, n);
    out.push_back({pos, is_max ? c : -c, is_max, prominence});
    i = j;
  }
}

}  // namespace

std::vector<Extremum> FindExtrema(std::span<const double> values, bool circular, const ExtremaOptions& options) {
  options.Check();
  std::vector<Extremum> result;
  for (bool is_max : {true, false}) {
    std::vector<Extremum> kind;
    FindPeaks(values, circular, is_max, kind);
    std::erase_if(kind, [&](const Extremum& e) { return e.prominence < options.min_prominence; });
    if (options.max_count > 0 && static_cast<int>(kind.size()) > options.max_count) {
      std::nth_element(kind.begin(), kind.begin() + options.max_count, kind.end(),
                       [](const Extremum& a, const Extremum& b) { return a.prominence > b.prominence; });
      kind.resize(options.max_count);
    }
    result.insert(result.end(), kind.begin(), kind.end());
  }
  std::sort(result.begin(), result.end(), [](const Extremum& a, const Extremum& b) { return a.position < b.position; });
  return result;
}

}  // namespace horizonreg
