// SPDX-License-Identifier: MIT
// Reading photos with clear errors.
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace horizonreg {

// Photos larger than this many pixels are refused before decoding (250
// million: a 3-byte BGR copy of 750 MB; the largest camera sensors have 100-
// 200 million).
inline constexpr double kDefaultMaxImagePixels = 250e6;

// Decodes an image file (JPEG, PNG, TIFF, ... as OpenCV reads them) to 8-bit
// BGR, applying the EXIF orientation. Throws IoError naming the file when it
// is missing, empty, truncated (a JPEG without its end marker) or not a
// decodable image; InvalidArgument when a JPEG's, PNG's, TIFF's, BMP's or
// WebP's header declares more than max_pixels pixels (checked before any
// pixel is decoded; the other formats OpenCV reads, e.g. JPEG 2000, PNM,
// OpenEXR, are bounded by OpenCV's own limit, 2^30). What the codec libraries
// print while decoding (a corrupt JPEG's "premature end of data segment") is
// kept from the standard error and, when `warnings` is given, added to it as
// one line naming the file. Thread-safe.
cv::Mat ReadImage(const std::string& path, double max_pixels = kDefaultMaxImagePixels,
                  std::vector<std::string>* warnings = nullptr);

// The width and height a JPEG (its first frame header), PNG (IHDR), TIFF
// (first IFD), BMP or WebP header declares, or nullopt for other or
// malformed data.
std::optional<std::pair<int, int>> DeclaredImageSize(const std::vector<unsigned char>& bytes);

}  // namespace horizonreg
