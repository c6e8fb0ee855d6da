// SPDX-License-Identifier: MIT
// Where the DEM horizon falls in an image at a given pose.
#pragma once

#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/register.h"

namespace horizonreg {

// Per image column, the y of the horizon projected at `pose` (linear between
// projected horizon bins; NaN outside). Faster than ProjectedHorizonRows.
std::vector<double> PredictedSkyline(const HorizonProfile& horizon, const CameraPose& pose, const CameraIntrinsics& k);

// Where a registered photo's skyline is expected, per image column: the DEM
// horizon projected at the pose (PredictedSkyline) and how far the skyline
// may lie above and below it under the DEM error model the registration was
// decided with (the options' model, its flattening scaled as the photo
// showed it, Registration::dem.flattening_scale): above by 4 mean
// flattenings (the one-sided tail's 98%) plus 3 sigma of the noise (the
// skyline's pixel noise and the position's uncertainty), below by those 3
// sigma. Pixels; NaN where no horizon is projected. Empty vectors when `r`
// has no pose (focal length 0).
struct SkylineWindow {
  std::vector<double> predicted, above_px, below_px;
};
SkylineWindow ExpectedSkylineWindow(const HorizonProfile& horizon, const Registration& r,
                                    const RegistrationOptions& options, int width, int height);

}  // namespace horizonreg
