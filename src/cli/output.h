// SPDX-License-Identifier: MIT
// CLI output helpers: atomic file writes and number formatting.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "util/json.h"

namespace horizonreg::cli {

// Writes `content` to `path` through a temporary file and a rename, so a
// failure never leaves a half-written file. "-" writes to stdout. Throws
// IoError naming the file.
void WriteOutput(const std::string& path, const std::string& content);

using horizonreg::Rounded;

}  // namespace horizonreg::cli
