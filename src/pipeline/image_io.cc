// SPDX-License-Identifier: MIT
#include "pipeline/image_io.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "util/errors.h"

namespace horizonreg {

cv::Mat ReadImage(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError("image: cannot open '" + path + "': no such file");
  std::ifstream f(path, std::ios::binary);
  std::vector<uchar> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (!f.good() && !f.eof()) throw IoError("image: cannot read '" + path + "'");
  if (bytes.empty()) throw IoError("image: '" + path + "' is empty");
  const bool jpeg = bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
  if (jpeg) {
    // A complete JPEG ends with the EOI marker FF D9 (allow a little trailing padding).
    bool eoi = false;
    for (size_t i = bytes.size() >= 64 ? bytes.size() - 64 : 0; i + 1 < bytes.size(); ++i)
      eoi = eoi || (bytes[i] == 0xFF && bytes[i + 1] == 0xD9);
    if (!eoi) throw IoError("image: '" + path + "' is a truncated JPEG (no end-of-image marker)");
  }
  cv::Mat image;
  try {
    // IMREAD_COLOR applies the EXIF orientation (phones store portrait photos
    // sideways with a rotation tag) and gives 8-bit BGR for any input depth.
    image = cv::imdecode(bytes, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    image.release();  // reported below with the file name
  }
  if (image.empty()) throw IoError("image: '" + path + "' is not a readable image");
  if (image.type() != CV_8UC3) throw IoError("image: '" + path + "' has an unsupported pixel type");
  return image;
}

}  // namespace horizonreg
