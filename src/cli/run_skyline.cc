// SPDX-License-Identifier: MIT
#include <CLI/CLI.hpp>
#include <chrono>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "pipeline/report.h"
#include "skyline/skyline.h"
#include "util/errors.h"
#include "util/text.h"

namespace horizonreg::cli {

void AddSkylineCommand(CLI::App& app, SkylineArgs& a) {
  CLI::App* c = app.add_subcommand("skyline", "Extract the sky/terrain boundary from a photo");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--json", a.json, "Write the JSON here instead of stdout");
  c->add_option("--debug", a.debug, "Draw the skyline over the photo into this PNG");
  c->add_option("--roll", a.roll, "Roll hint from an inclinometer, degrees (positive: right side down)");
  AddMaxImageOption(*c, a.max_image_mpx);
}

int RunSkyline(const SkylineArgs& a) {
  SkylineOptions o;
  o.roll_hint_deg = a.roll;
  o.Check();
  std::vector<std::string> warnings;
  const cv::Mat image = ReadImage(a.image, a.max_image_mpx * 1e6, &warnings);
  for (const std::string& w : warnings) std::cerr << "horizonreg: warning: " << w << "\n";
  const auto t0 = std::chrono::steady_clock::now();
  const Skyline s = ExtractSkyline(image, o);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json j = SkylineJson(s);
  j["timing_ms"] = {{"skyline", Rounded(ms, 2)}};
  if (!a.debug.empty()) WriteImage(a.debug, DrawSkylineDebug(image, s));
  WriteOutput(a.json.empty() ? "-" : a.json, j.dump() + "\n");
  return 0;
}

Skyline ReadSkylineJson(const std::string& path, int width, int height) {
  // A skyline JSON has a few numbers per column: 64 MB is a 1 M-column image's.
  const nlohmann::json j =
      nlohmann::json::parse(ReadTextFile(path, "skyline", size_t{64} << 20), nullptr, /*allow_exceptions=*/false);
  auto bad = [&](const std::string& what) -> Skyline { throw InvalidArgument("skyline: '" + path + "': " + what); };
  if (!j.is_object() || !j.contains("y") || !j["y"].is_array()) return bad("not a skyline JSON (no \"y\" array)");
  if (!j.contains("width") || !j["width"].is_number_integer() || !j.contains("height") ||
      !j["height"].is_number_integer())
    return bad("no integer \"width\" and \"height\"");
  if (j["width"].get<int>() != width || j["height"].get<int>() != height || static_cast<int>(j["y"].size()) != width)
    return bad("not for a " + std::to_string(width) + " x " + std::to_string(height) + " image");
  Skyline s;
  s.width = width;
  s.height = height;
  s.y.assign(width, NAN);
  s.confidence.assign(width, 0.0);
  const bool has_conf =
      j.contains("confidence") && j["confidence"].is_array() && j["confidence"].size() == j["y"].size();
  // Column x of array `key`: a row number, or NaN for null.
  auto row = [&](const char* key, int x) {
    const auto& v = j[key][x];
    if (v.is_null()) return static_cast<double>(NAN);
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < -height ||
        v.get<double>() > 2.0 * height)
      bad(std::string(key) + "[" + std::to_string(x) + "] is not a row number or null");
    return v.get<double>();
  };
  for (int x = 0; x < width; ++x) {
    s.y[x] = row("y", x);
    if (!std::isfinite(s.y[x])) continue;
    s.confidence[x] =
        has_conf && j["confidence"][x].is_number() ? std::clamp(j["confidence"][x].get<double>(), 0.0, 1.0) : 1.0;
  }
  // The edges the matching reads below raised boundaries (SkylineJson), if any.
  if (j.contains("y_alt")) {
    if (!j["y_alt"].is_array() || j["y_alt"].size() != j["y"].size())
      return bad("\"y_alt\" is not an array of one row or null per column");
    s.y_alt.assign(width, NAN);
    for (int x = 0; x < width; ++x)
      if (const double v = row("y_alt", x); std::isfinite(s.y[x])) s.y_alt[x] = v;
  }
  return s;
}

}  // namespace horizonreg::cli
