// SPDX-License-Identifier: MIT
#include "cli/output.h"

#include <filesystem>
#include <fstream>
#include <iostream>

#include "util/errors.h"

namespace horizonreg::cli {

void WriteOutput(const std::string& path, const std::string& content) {
  if (path == "-") {
    std::cout << content;
    std::cout.flush();
    if (!std::cout) throw IoError("cannot write to standard output");
    return;
  }
  const std::filesystem::path out(path);
  std::error_code dir_ec;
  if (std::filesystem::is_directory(out, dir_ec) || !out.has_filename())
    throw InvalidArgument("cannot write '" + path + "': a directory, not a file");
  const std::filesystem::path tmp = out.parent_path() / ("." + out.filename().string() + ".tmp");
  {
    std::ofstream f(tmp, std::ios::binary);
    if (f) f << content;
    f.flush();
    if (!f) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw IoError("cannot write '" + path + "'");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw IoError("cannot write '" + path + "': " + ec.message());
  }
}

}  // namespace horizonreg::cli
