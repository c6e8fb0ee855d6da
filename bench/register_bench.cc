// SPDX-License-Identifier: MIT
// Matching speed (paper, section 4.4: 75 hypotheses scored in 0.5 s on a
// 200 MHz Pentium Pro): Register() alone (default options: 2 threads), and
// on one thread, on dev scenes whose DEM
// horizon and skyline are computed once beforehand. Needs ../shared; skips
// with a message without it.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "match/register.h"
#include "testing/shared_data.h"

namespace horizonreg {
namespace {

struct Scene {
  Skyline skyline;
  HorizonProfile horizon;
};

std::optional<Scene> LoadScene(const std::string& name) {
  const auto shared = testing::SharedDir();
  if (!shared) return std::nullopt;
  const auto dir = *shared / "scenes" / "dev";
  const auto t = nlohmann::json::parse(std::ifstream(dir / (name + ".truth.json")));
  const Terrain terrain({(*shared / "dem" / t["dem"].get<std::string>()).string()});
  HorizonOptions o;
  o.azimuth_step_deg = 0.1;  // as `register` uses
  const TerrainWindow w = terrain.ReadWindow({t["lat"], t["lon"], 0.0}, o.max_distance_m);
  const GeodeticPoint eye = ResolveObserver(w, t["lat"], t["lon"], t["agl_m"].get<double>(), std::nullopt);
  Scene s{ExtractSkyline(cv::imread((dir / (name + ".jpg")).string()), SkylineOptions{}), ComputeHorizon(w, eye, o)};
  return s;
}

void BM_Register(benchmark::State& state, const std::string& name) {
  const auto scene = LoadScene(name);
  if (!scene) return state.SkipWithError("../shared is absent");
  RegistrationOptions options;
  options.num_threads = static_cast<int>(state.range(0));
  int hypotheses = 0;
  for (auto _ : state) {
    const Registration r = Register(scene->skyline, scene->horizon, options);
    hypotheses = r.hypotheses;
    benchmark::DoNotOptimize(r);
  }
  state.counters["hypotheses"] = hypotheses;
}
// Argument: threads. Wall time (the threads' work is not the caller's CPU time).
BENCHMARK_CAPTURE(BM_Register, alps_03, std::string("alps_03"))
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Register, rainier_04, std::string("rainier_04"))
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Register, zion_01, std::string("zion_01"))
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace horizonreg

int main(int argc, char** argv) {
  std::printf("Paper (Behringer 1999): 75 hypotheses scored in < 0.5 s.\n");
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
