// SPDX-License-Identifier: MIT
#include <CLI/CLI.hpp>
#include <chrono>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "skyline/skyline.h"

namespace horizonreg::cli {

void AddSkylineCommand(CLI::App& app, SkylineArgs& a) {
  CLI::App* c = app.add_subcommand("skyline", "Extract the sky/terrain boundary from a photo");
  c->add_option("image", a.image, "Photo (JPEG, PNG, ...)")->required();
  c->add_option("--json", a.json, "Write the JSON here instead of stdout");
  c->add_option("--debug", a.debug, "Draw the skyline over the photo into this PNG");
  c->add_option("--roll", a.roll, "Roll hint from an inclinometer, degrees (positive: right side down)");
}

int RunSkyline(const SkylineArgs& a) {
  SkylineOptions o;
  o.roll_hint_deg = a.roll;
  o.Check();
  const cv::Mat image = ReadImage(a.image);
  const auto t0 = std::chrono::steady_clock::now();
  const Skyline s = ExtractSkyline(image, o);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json j;
  j["width"] = s.width;
  j["height"] = s.height;
  nlohmann::json ys = nlohmann::json::array(), cs = nlohmann::json::array();
  for (int x = 0; x < s.width; ++x) {
    ys.push_back(Rounded(s.y[x], 2));
    cs.push_back(Rounded(s.confidence[x], 3));
  }
  j["y"] = std::move(ys);
  j["confidence"] = std::move(cs);
  j["visible_columns"] = s.VisibleCount();
  j["timing_ms"] = {{"skyline", Rounded(ms, 2)}};
  if (!a.debug.empty()) WriteImage(a.debug, DrawSkylineDebug(image, s));
  WriteOutput(a.json.empty() ? "-" : a.json, j.dump() + "\n");
  return 0;
}

}  // namespace horizonreg::cli
