// SPDX-License-Identifier: MIT
// Batch inputs (pipeline ReadStations, ReadManifest): stations and manifest
// CSV or JSON. The input is read both as a stations file and as a manifest
// (against the stations it defined, when it was a valid stations file).
#include <map>

#include "fuzz/fuzz_util.h"
#include "pipeline/batch.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  const std::string path = fuzz::WriteScratch("batch.csv", data, size);
  std::map<std::string, BatchStation> stations;
  fuzz::ExpectingBadInput([&] { stations = ReadStations(path); });
  fuzz::ExpectingBadInput([&] { (void)ReadManifest(path, stations); });
  return 0;
}
