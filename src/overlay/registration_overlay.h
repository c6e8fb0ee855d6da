// SPDX-License-Identifier: MIT
// Quick check of a registration: the DEM horizon projected at the recovered
// pose, drawn over the photo (paper, section 4.5: "the silhouette ... as a
// reference for the registration quality").
#pragma once

#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"

namespace cv {
class Mat;
}

namespace horizonreg {

// Returns a BGR copy of `image` with the horizon drawn as a polyline
// (coloured by distance: near red, far blue), the measured skyline (thin
// white, may be empty) and one line of `caption` at the top. Line widths and
// text scale with the image size. Thread-safe.
cv::Mat DrawHorizonCheck(const cv::Mat& image, const HorizonProfile& horizon, const CameraPose& pose,
                         const CameraIntrinsics& intrinsics, const std::vector<double>& skyline_y,
                         const std::string& caption);

}  // namespace horizonreg
