// SPDX-License-Identifier: MIT
// Reading photos with clear errors.
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace horizonreg {

// Decodes an image file (JPEG, PNG, TIFF, ... as OpenCV reads them) to 8-bit
// BGR, applying the EXIF orientation. Throws IoError naming the file when it
// is missing, empty, truncated (a JPEG without its end marker) or not a
// decodable image. Thread-safe.
cv::Mat ReadImage(const std::string& path);

}  // namespace horizonreg
