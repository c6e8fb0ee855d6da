// SPDX-License-Identifier: MIT
// Tracking speed: one frame followed from the previous one (band skyline +
// robust refinement), 1280 x 720, one core, on the rainier_pan sequence
// upscaled. Target 10 ms (>= 100 fps). Needs ../shared; skips without it.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "testing/shared_data.h"
#include "track/track.h"

namespace horizonreg {
namespace {

void BM_TrackFrame(benchmark::State& state) {
  cv::setNumThreads(1);
  const auto shared = testing::SharedDir();
  if (!shared) return state.SkipWithError("../shared is absent");
  const auto seq = *shared / "scenes" / "seq";
  std::vector<cv::Mat> frames;
  for (int f = 10; f < 30; ++f) {
    char name[64];
    std::snprintf(name, sizeof name, "rainier_pan_%04d.jpg", f);
    cv::Mat img = cv::imread((seq / name).string());
    cv::resize(img, img, cv::Size(1280, 854), 0, 0, cv::INTER_LINEAR);  // square pixels,
    frames.push_back(img.rowRange(67, 787).clone());                    // centred crop to 720 rows
  }
  const Terrain terrain({(*shared / "dem" / "mt_rainier_90m.tif").string()});
  const TerrainWindow w = terrain.ReadWindow({46.86146, -121.57288, 0.0}, 100'000.0);
  HorizonOptions ho;
  ho.azimuth_step_deg = 0.1;
  const HorizonProfile horizon = ComputeHorizon(w, ResolveObserver(w, 46.86146, -121.57288, 1.7, std::nullopt), ho);
  auto tracker = std::make_unique<Tracker>(horizon, 1280, 720, TrackerOptions{});
  // Register (Process) until the first visual pose, then time Process on the
  // following frames: tracked from the previous pose with the motion model,
  // re-registered when tracking fails (counted in tracked_share).
  size_t i = 0;
  while (i < frames.size() &&
         tracker->Process(frames[i], static_cast<int>(i), std::nullopt, i / 10.0).source != PoseSource::kVision)
    ++i;
  if (i + 2 >= frames.size()) return state.SkipWithError("no frame registered");
  const size_t start = ++i;
  int tracked = 0, total = 0;
  for (auto _ : state) {
    if (i == frames.size()) {  // rewind: restart from a fresh tracker state
      state.PauseTiming();
      tracker = std::make_unique<Tracker>(horizon, 1280, 720, TrackerOptions{});
      for (size_t j = 0; j < start; ++j) tracker->Process(frames[j], static_cast<int>(j), std::nullopt, j / 10.0);
      i = start;
      state.ResumeTiming();
    }
    const FramePose p = tracker->Process(frames[i], static_cast<int>(i), std::nullopt, i / 10.0);
    ++total;
    tracked += p.source == PoseSource::kTracked;
    ++i;
  }
  state.counters["tracked_share"] = static_cast<double>(tracked) / std::max(1, total);
}
BENCHMARK(BM_TrackFrame)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace horizonreg

int main(int argc, char** argv) {
  std::printf("Target: tracking a 1280 x 720 frame in <= 10 ms on one core.\n");
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
