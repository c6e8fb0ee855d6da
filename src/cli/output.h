// SPDX-License-Identifier: MIT
// CLI output helpers: atomic file writes and number formatting.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

namespace horizonreg::cli {

// Writes `content` to `path` through a temporary file and a rename, so a
// failure never leaves a half-written file. "-" writes to stdout. Throws
// IoError naming the file.
void WriteOutput(const std::string& path, const std::string& content);

// A JSON number rounded to `decimals`, or null for NaN / infinity.
inline nlohmann::json Rounded(double v, int decimals) {
  if (!std::isfinite(v)) return nullptr;
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

}  // namespace horizonreg::cli
