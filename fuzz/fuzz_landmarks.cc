// SPDX-License-Identifier: MIT
// Landmark files (overlay LoadLandmarks): GeoJSON FeatureCollections of
// Points and CSV name,lat,lon[,ele].
#include <cmath>
#include <cstdlib>

#include "fuzz/fuzz_util.h"
#include "overlay/landmarks.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  const std::string path = fuzz::WriteScratch("landmarks.txt", data, size);
  fuzz::ExpectingBadInput([&] {
    for (const Landmark& l : LoadLandmarks(path))
      if (!(std::abs(l.lat_deg) <= 90) || !std::isfinite(l.lon_deg)) std::abort();  // documented: out of range throws
  });
  return 0;
}
