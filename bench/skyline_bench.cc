// SPDX-License-Identifier: MIT
// Skyline extraction speed (paper, section 4.3: 1 s for a 512 x 480 frame on
// a 200 MHz Pentium Pro), one core, on a dev scene at 1024 x 683 and scaled
// to 4000 x 3000. Needs ../shared/scenes; skips with a message without it.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "skyline/refine.h"
#include "skyline/skyline.h"
#include "skyline/vignetting.h"
#include "testing/pixel_noise.h"
#include "testing/shared_data.h"

namespace horizonreg {
namespace {

cv::Mat LoadScene(int width, int height) {
  const auto shared = testing::SharedDir();
  if (!shared) return {};
  cv::Mat img = cv::imread((*shared / "scenes" / "dev" / "rainier_04.jpg").string());
  if (!img.empty() && img.cols != width) cv::resize(img, img, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
  return img;
}

void BM_Skyline(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat img = LoadScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (img.empty()) return state.SkipWithError("../shared is absent");
  for (auto _ : state) benchmark::DoNotOptimize(ExtractSkyline(img, SkylineOptions{}));
}
BENCHMARK(BM_Skyline)->Args({1024, 683})->Args({4000, 3000})->Unit(benchmark::kMillisecond);

// The noise estimate every photo up to 1.5 times the extraction's width
// pays (skyline_detail::NoiseSigma; wider ones are read as block means) ...
void BM_NoiseSigma(benchmark::State& state) {
  const cv::Mat img = LoadScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (img.empty()) return state.SkipWithError("../shared is absent");
  for (auto _ : state) benchmark::DoNotOptimize(skyline_detail::NoiseSigma(img));
}
BENCHMARK(BM_NoiseSigma)->Args({1024, 683})->Unit(benchmark::kMillisecond);

// ... and the lens's fall-off every photo is read for (EstimateVignetting),
// at 1024 x 683 and 4000 x 3000.
void BM_EstimateVignetting(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat img = LoadScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (img.empty()) return state.SkipWithError("../shared is absent");
  for (auto _ : state) benchmark::DoNotOptimize(EstimateVignetting(img));
}
BENCHMARK(BM_EstimateVignetting)->Args({1024, 683})->Args({4000, 3000})->Unit(benchmark::kMillisecond);

// ... and the whole extraction of a noisy frame (sigma 6 per channel), which
// is smoothed first.
void BM_SkylineNoisy(benchmark::State& state) {
  cv::setNumThreads(1);
  cv::Mat img = LoadScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  if (img.empty()) return state.SkipWithError("../shared is absent");
  testing::AddPixelNoise(img, 6.0);
  for (auto _ : state) benchmark::DoNotOptimize(ExtractSkyline(img, SkylineOptions{}));
}
BENCHMARK(BM_SkylineNoisy)->Args({1024, 683})->Unit(benchmark::kMillisecond);

// ... and of a hazy real photo (AK01b_20100525, 724 x 486, its lightness
// spanning about 56 of L*'s 100), whose rows are read a second time with
// the least clear step judged over that span (LightnessStretch): the
// extraction's steps after the refinement run twice (measured 2026-12-07:
// 41-43 ms before, 46-47 ms with it).
void BM_SkylineHazyReal(benchmark::State& state) {
  cv::setNumThreads(1);
  const auto shared = testing::SharedDir();
  const cv::Mat img =
      shared ? cv::imread((*shared / "real" / "columbia" / "AK01b_20100525_200710.jpg").string()) : cv::Mat();
  if (img.empty()) return state.SkipWithError("../shared is absent");
  for (auto _ : state) benchmark::DoNotOptimize(ExtractSkyline(img, SkylineOptions{}));
}
BENCHMARK(BM_SkylineHazyReal)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace horizonreg

int main(int argc, char** argv) {
  std::printf("Paper (Behringer 1999): skyline of a 512 x 480 frame in 1 s.\n");
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
