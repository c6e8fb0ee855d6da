// SPDX-License-Identifier: MIT
// Reading photos for the CLI with clear errors (OpenCV only here and in the
// drawing modules).
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "pipeline/image_io.h"

namespace horizonreg::cli {

using horizonreg::ReadImage;  // pipeline/image_io.h

// Encodes an image by the file's extension and writes it atomically.
void WriteImage(const std::string& path, const cv::Mat& image);

}  // namespace horizonreg::cli
