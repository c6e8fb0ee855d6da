// SPDX-License-Identifier: MIT
#include "pipeline/image_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "util/errors.h"

namespace horizonreg {
namespace {

namespace fs = std::filesystem;

std::vector<unsigned char> Encode(const std::string& ext, int w, int h) {
  std::vector<unsigned char> out;
  cv::imencode(ext, cv::Mat(h, w, CV_8UC3, cv::Scalar(10, 200, 30)), out);
  return out;
}

TEST(DeclaredImageSize, ReadsJpegAndPngHeaders) {
  EXPECT_EQ(DeclaredImageSize(Encode(".jpg", 123, 45)), std::make_pair(123, 45));
  EXPECT_EQ(DeclaredImageSize(Encode(".png", 7, 300)), std::make_pair(7, 300));
  EXPECT_FALSE(DeclaredImageSize(Encode(".bmp", 7, 3)));
  EXPECT_FALSE(DeclaredImageSize({0xFF, 0xD8, 0xFF}));  // too short
  EXPECT_FALSE(DeclaredImageSize({}));
}

TEST(ReadImage, RefusesADeclaredSizeAboveTheLimitBeforeDecoding) {
  const fs::path p = fs::temp_directory_path() / ("hr_image_io_" + std::to_string(::getpid()) + ".jpg");
  const auto bytes = Encode(".jpg", 400, 300);
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<long>(bytes.size()));
  EXPECT_EQ(ReadImage(p.string()).cols, 400);
  try {
    ReadImage(p.string(), 100'000.0);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("400 x 300"), std::string::npos) << e.what();
  }
  std::vector<std::string> warnings;
  ReadImage(p.string(), kDefaultMaxImagePixels, &warnings);
  EXPECT_TRUE(warnings.empty());
  fs::remove(p);
}

}  // namespace
}  // namespace horizonreg
