// SPDX-License-Identifier: MIT
// The register JSON (DESIGN.md) of a photo registered at a Site, and its
// overlay: one builder for `register`, `batch` and Python, so that they give
// the same answer field by field.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "pipeline/register_photo.h"
#include "pipeline/site.h"

namespace cv {
class Mat;
}

namespace horizonreg {

// DESIGN.md's register JSON. `position_source` is the observer's source
// ("arguments", "sensors" or "exif"); timing_ms holds the site's
// horizon time, the photo's skyline and match times and `total_ms`.
nlohmann::json RegistrationReport(const Site& site, const PhotoRegistration& photo, const std::string& position_source,
                                  double total_ms);

// DESIGN.md's skyline JSON (`skyline`, `register --skyline-out`, batch and
// Python rows' "skyline"): width, height, y and confidence per column (null
// where not visible) and visible_columns.
nlohmann::json SkylineJson(const Skyline& s);

// The overlay of a registered photo at its recovered pose (DEM silhouette,
// ridges, landmarks from `landmarks_path` or the horizon's summits), or the
// skyline debug image captioned with the reason when it did not register.
cv::Mat DrawRegistration(const Site& site, const cv::Mat& image, const PhotoRegistration& photo,
                         const std::string& landmarks_path);

}  // namespace horizonreg
