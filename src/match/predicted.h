// SPDX-License-Identifier: MIT
// Where the DEM horizon falls in an image at a given pose.
#pragma once

#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"

namespace horizonreg {

// Per image column, the y of the horizon projected at `pose` (linear between
// projected horizon bins; NaN outside). Faster than ProjectedHorizonRows.
std::vector<double> PredictedSkyline(const HorizonProfile& horizon, const CameraPose& pose, const CameraIntrinsics& k);

}  // namespace horizonreg
