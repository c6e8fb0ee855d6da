// SPDX-License-Identifier: MIT
// A panorama chart of a horizon profile: elevation angle against azimuth,
// terrain filled and shaded by distance, inner ridge lines, compass labels.
#pragma once

#include <string>
#include <vector>

#include "horizon/horizon.h"

namespace horizonreg {

struct HorizonPlotOptions {
  int width_px = 1800;    // image width, >= 400
  int height_px = 560;    // image height, >= 200
  std::string title;      // drawn at the top left
  void Check() const;
};

// Writes the chart to `path` (PNG or any format OpenCV writes, by extension).
// `ridges` may be empty. Throws IoError when the file cannot be written,
// InvalidArgument on bad options.
void PlotHorizon(const HorizonProfile& profile, const std::vector<std::vector<Ridge>>& ridges,
                 const HorizonPlotOptions& options, const std::string& path);

}  // namespace horizonreg
