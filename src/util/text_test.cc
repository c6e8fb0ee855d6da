// SPDX-License-Identifier: MIT
#include "util/text.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace horizonreg {
namespace {

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("horizonreg_text_test_" + name)).string();
}

TEST(ReadTextFile, ReadsAWholeFile) {
  const std::string path = TempPath("ok.txt");
  std::string text(200'000, 'a');  // more than one block
  text += "\nend";
  std::ofstream(path, std::ios::binary) << text;
  EXPECT_EQ(ReadTextFile(path, "test"), text);
  std::filesystem::remove(path);
}

TEST(ReadTextFile, RefusesAFileOverItsBound) {
  const std::string path = TempPath("big.txt");
  std::ofstream(path, std::ios::binary) << std::string((size_t{1} << 20) + 1, 'x');
  try {
    ReadTextFile(path, "test", size_t{1} << 20);
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("more than the 1 MB"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

TEST(ReadTextFile, RefusesADirectoryByName) {
  const std::string dir = TempPath("dir");
  std::filesystem::create_directories(dir);
  try {
    ReadTextFile(dir, "sensors");
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(std::string(e.what()), "sensors: '" + dir + "' is a directory, not a file");
  }
  std::filesystem::remove(dir);
}

TEST(ReadTextFile, StopsReadingADeviceWithoutASizeAtItsBound) {
  // /dev/zero has no size to check first: read until the bound, then refused
  // (it was read until the OOM killer came).
  if (!std::filesystem::exists("/dev/zero")) GTEST_SKIP() << "no /dev/zero";
  EXPECT_THROW(ReadTextFile("/dev/zero", "camera", size_t{1} << 20), InvalidArgument);
}

TEST(ReadTextFile, AMissingFileIsAnIoError) {
  EXPECT_THROW(ReadTextFile(TempPath("missing.txt"), "test"), IoError);
}

}  // namespace
}  // namespace horizonreg
