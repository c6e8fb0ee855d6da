// SPDX-License-Identifier: MIT
#include "cli/image_io.h"

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "cli/output.h"
#include "util/errors.h"

namespace horizonreg::cli {

void WriteImage(const std::string& path, const cv::Mat& image) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (ext.empty()) ext = ".png";
  std::vector<uchar> buf;
  bool ok = false;
  try {
    ok = cv::imencode(ext, image, buf);
  } catch (const cv::Exception&) {
    ok = false;  // reported below with the file name
  }
  if (!ok) throw IoError("cannot encode '" + path + "' (unknown image extension?)");
  WriteOutput(path, std::string(buf.begin(), buf.end()));
}

}  // namespace horizonreg::cli
