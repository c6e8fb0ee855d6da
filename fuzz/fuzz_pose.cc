// SPDX-License-Identifier: MIT
// The CLI's own JSON inputs: the pose `overlay --pose` reads (cli
// ReadPoseFile: register --json output, with its optional "camera" block in
// the camera-file layout) and the skyline `register --skyline` reads (cli
// ReadSkylineJson, for a 64 x 48 image).
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "cli/commands.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  const std::string path = fuzz::WriteScratch("pose.json", data, size);
  fuzz::ExpectingBadInput([&] {
    const cli::CameraPoseFile p = cli::ReadPoseFile(path);
    if (p.width < 1 || p.height < 1 || !(p.focal_px > 0)) std::abort();
    // What overlay does next with it.
    (void)p.intrinsics.Resized(std::max(1, p.width / 2), std::max(1, p.height / 2));
  });
  fuzz::ExpectingBadInput([&] {
    const Skyline s = cli::ReadSkylineJson(path, 64, 48);
    if (s.y.size() != 64 || s.confidence.size() != 64) std::abort();
    // y_alt: none, or one per column, set only under a boundary.
    if (!s.y_alt.empty() && s.y_alt.size() != 64) std::abort();
    for (int x = 0; x < 64; ++x)
      if (std::isfinite(s.Alt(x)) && !std::isfinite(s.y[x])) std::abort();
  });
  return 0;
}
