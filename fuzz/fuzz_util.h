// SPDX-License-Identifier: MIT
// Shared by the fuzz targets: the library reads files by name, so each input
// is written to a scratch file (in /dev/shm when it exists) under the name
// the parser expects (an extension picks the GDAL driver or the format).
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "util/errors.h"

namespace horizonreg::fuzz {

// A per-process scratch folder, removed at exit.
inline const std::filesystem::path& ScratchDir() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path base = std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
    std::filesystem::path d = base / ("horizonreg_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(ScratchDir(), ec);
    });
    return d;
  }();
  return dir;
}

// Writes bytes to ScratchDir()/name and returns the path.
inline std::string WriteScratch(const std::string& name, const uint8_t* data, size_t size) {
  const std::filesystem::path p = ScratchDir() / name;
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  f.close();
  if (!f) std::abort();  // the harness itself failed: not a finding in the library
  return p.string();
}

// Runs `body`, swallowing the errors the library documents for bad input
// (InvalidArgument, IoError). Anything else (LogicError = a broken internal
// check, other exceptions, crashes, sanitizer reports) escapes to libFuzzer.
// HORIZONREG_FUZZ_VERBOSE=1 prints their messages (to check what a seed reaches).
template <typename F>
void ExpectingBadInput(F&& body) {
  static const bool verbose = std::getenv("HORIZONREG_FUZZ_VERBOSE") != nullptr;
  try {
    body();
    if (verbose) std::fprintf(stderr, "fuzz: accepted\n");
  } catch (const InvalidArgument& e) {
    if (verbose) std::fprintf(stderr, "fuzz: InvalidArgument: %s\n", e.what());
  } catch (const IoError& e) {
    if (verbose) std::fprintf(stderr, "fuzz: IoError: %s\n", e.what());
  }
}

}  // namespace horizonreg::fuzz
