// SPDX-License-Identifier: MIT
// Reading photos for the CLI with clear errors (OpenCV only here and in the
// drawing modules).
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace horizonreg::cli {

// Decodes an image file (JPEG, PNG, TIFF, ... as OpenCV reads them). Throws
// IoError naming the file when it is missing, empty, truncated (a JPEG
// without its end marker) or not a decodable image.
cv::Mat ReadImage(const std::string& path);

// Encodes an image by the file's extension and writes it atomically.
void WriteImage(const std::string& path, const cv::Mat& image);

}  // namespace horizonreg::cli
