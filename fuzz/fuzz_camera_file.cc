// SPDX-License-Identifier: MIT
// Camera files (`--camera`, pipeline ReadCameraFile): the plain camera JSON
// and OpenCV calibration output read by cv::FileStorage (YAML, JSON; XML and
// .gz are refused before it).
// The first input byte picks the file extension (FileStorage goes by it) and
// the image size the file is read for.
#include <cstdlib>

#include "fuzz/fuzz_util.h"
#include "pipeline/camera_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace horizonreg;
  if (size < 1) return 0;
  static const char* const kNames[] = {"camera.yml", "camera.json", "camera.xml", "camera.yaml"};
  static const int kSizes[][2] = {{640, 480}, {4000, 3000}, {1920, 1080}, {1, 1}};
  const std::string path = fuzz::WriteScratch(kNames[data[0] & 3], data + 1, size - 1);
  const int* image = kSizes[(data[0] >> 2) & 3];
  fuzz::ExpectingBadInput([&] {
    const CameraIntrinsics k = ReadCameraFile(path, image[0], image[1]);
    if (k.width != image[0] || k.height != image[1] || !(k.focal_px > 0)) std::abort();
  });
  return 0;
}
