// SPDX-License-Identifier: MIT
// Sensor files: the per-frame log (sensors ReadSensorLog: CSV, or a JSON
// array) and the single-reading JSON (ReadSensorJson, `--sensors`).
#include <cmath>
#include <cstdlib>

#include "fuzz/fuzz_util.h"
#include "sensors/sensors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  const std::string path = fuzz::WriteScratch("sensors.csv", data, size);
  fuzz::ExpectingBadInput([&] {
    const SensorLog log = ReadSensorLog(path);
    if (log.entries.empty()) std::abort();  // documented: no usable row is InvalidArgument
    for (const int frame : {0, 1, 100}) (void)log.ForFrame(frame, 30.0);
  });
  fuzz::ExpectingBadInput([&] {
    const SensorReading r = ReadSensorJson(path);
    if (r.pitch_deg && !(std::abs(*r.pitch_deg) <= 90)) std::abort();  // documented range
    if (r.lat_deg && !(std::abs(*r.lat_deg) <= 90)) std::abort();
  });
  return 0;
}
