// SPDX-License-Identifier: MIT
// A panorama chart of a horizon profile: elevation angle against azimuth,
// terrain filled and shaded by distance, inner ridge lines, compass labels.
#pragma once

#include <string>
#include <vector>

#include "horizon/horizon.h"

namespace cv {
class Mat;
}

namespace horizonreg {

struct HorizonPlotOptions {
  int width_px = 1800;  // image width, >= 400
  int height_px = 560;  // image height, >= 200
  std::string title;    // drawn at the top left
  void Check() const;
};

// Draws the chart (8-bit BGR, width_px x height_px); the caller writes it.
// `ridges` may be empty. Throws InvalidArgument on bad options.
cv::Mat PlotHorizon(const HorizonProfile& profile, const std::vector<std::vector<Ridge>>& ridges,
                    const HorizonPlotOptions& options);

}  // namespace horizonreg
