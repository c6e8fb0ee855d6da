// SPDX-License-Identifier: MIT
// EXIF reading (sensors ReadExif through exiv2): a photo's GPS position,
// altitude, direction and 35 mm focal length. ReadExif never throws for
// malformed metadata, so any exception escaping it is a finding.
#include "fuzz/fuzz_util.h"
#include "sensors/sensors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  // exiv2 picks the format from the content; the extension is not read.
  const std::string path = fuzz::WriteScratch("photo.jpg", data, size);
  const SensorReading r = ReadExif(path);
  (void)r;
  return 0;
}
