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

std::vector<unsigned char> Encode(const std::string& ext, int w, int h, const std::vector<int>& params = {}) {
  std::vector<unsigned char> out;
  cv::imencode(ext, cv::Mat(h, w, CV_8UC3, cv::Scalar(10, 200, 30)), out, params);
  return out;
}

TEST(DeclaredImageSize, ReadsJpegPngTiffBmpAndWebpHeaders) {
  EXPECT_EQ(DeclaredImageSize(Encode(".jpg", 123, 45)), std::make_pair(123, 45));
  EXPECT_EQ(DeclaredImageSize(Encode(".png", 7, 300)), std::make_pair(7, 300));
  EXPECT_EQ(DeclaredImageSize(Encode(".bmp", 7, 3)), std::make_pair(7, 3));
  EXPECT_EQ(DeclaredImageSize(Encode(".tif", 70000, 2)), std::make_pair(70000, 2));  // LONG width
  EXPECT_EQ(DeclaredImageSize(Encode(".tif", 9, 4)), std::make_pair(9, 4));
  EXPECT_EQ(DeclaredImageSize(Encode(".webp", 33, 17)), std::make_pair(33, 17));                                // lossy
  EXPECT_EQ(DeclaredImageSize(Encode(".webp", 33, 17, {cv::IMWRITE_WEBP_QUALITY, 101})), std::make_pair(33, 17));  // lossless
  EXPECT_FALSE(DeclaredImageSize(Encode(".ppm", 7, 3)));
  EXPECT_FALSE(DeclaredImageSize({'I', 'I', 42, 0, 200, 0, 0, 0}));  // IFD beyond the end
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

TEST(ReadImage, RefusesATiffDeclaringTooManyPixelsBeforeDecoding) {
  // A bare little-endian TIFF header: one IFD with ImageWidth and ImageLength
  // (LONG) of 100000, no pixel data.
  std::vector<unsigned char> tiff = {'I', 'I', 42, 0, 8, 0, 0, 0, 2, 0};
  for (const unsigned tag : {256u, 257u})
    tiff.insert(tiff.end(), {static_cast<unsigned char>(tag & 0xff), static_cast<unsigned char>(tag >> 8), 4, 0, 1, 0, 0,
                             0, 0xa0, 0x86, 0x01, 0x00});
  tiff.insert(tiff.end(), {0, 0, 0, 0});
  const fs::path p = fs::temp_directory_path() / ("hr_image_io_" + std::to_string(::getpid()) + ".tif");
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(tiff.data()), static_cast<long>(tiff.size()));
  try {
    ReadImage(p.string());
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("100000 x 100000"), std::string::npos) << e.what();
  }
  fs::remove(p);
}

}  // namespace
}  // namespace horizonreg
