// SPDX-License-Identifier: MIT
// Photo decoding (pipeline ReadImage: every codec OpenCV's imdecode reaches,
// the JPEG/PNG size check, the EXIF orientation) and skyline extraction on
// whatever decodes.
#include <cstdlib>
#include <opencv2/core.hpp>

#include "fuzz/fuzz_util.h"
#include "pipeline/image_io.h"
#include "skyline/skyline.h"

namespace {
// Small bounds keep each input fast: 1 million pixels for the formats whose
// header ReadImage checks; OpenCV's own limit for the others.
constexpr double kMaxPixels = 1 << 20;
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // OpenCV reads this once, at the first decode: bounds the formats whose
  // size ReadImage does not check itself (otherwise 2^30 pixels).
  setenv("OPENCV_IO_MAX_IMAGE_PIXELS", "4194304", 0);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  const std::string path = fuzz::WriteScratch("photo", data, size);
  fuzz::ExpectingBadInput([&] {
    std::vector<std::string> warnings;
    const cv::Mat image = ReadImage(path, kMaxPixels, &warnings);
    if (image.total() > kMaxPixels) return;  // a TIFF, BMP, ... larger than the budget: decoding was the test
    SkylineOptions options;
    options.max_work_width_px = 256;
    const Skyline s = ExtractSkyline(image, options);
    if (s.width != image.cols || s.height != image.rows || s.y.size() != static_cast<size_t>(image.cols)) std::abort();
  });
  return 0;
}
