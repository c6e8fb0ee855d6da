// SPDX-License-Identifier: MIT
// JSON parsing of input files with the project's error messages.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "util/errors.h"

namespace horizonreg {

// Parses `text`; throws InvalidArgument "<what>: '<source>' is not valid JSON (<reason>)".
inline nlohmann::json ParseJson(const std::string& text, const std::string& what, const std::string& source) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InvalidArgument(what + ": '" + source + "' is not valid JSON (" + e.what() + ")");
  }
}

// A JSON number rounded to `decimals`, or null for NaN / infinity.
inline nlohmann::json Rounded(double v, int decimals) {
  if (!std::isfinite(v)) return nullptr;
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

}  // namespace horizonreg
