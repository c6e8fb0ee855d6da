// SPDX-License-Identifier: MIT
// Horizon benchmarks next to the paper's figures (section 4.2: 40 s for the
// full 1201 x 1201 USGS DEM at 0.25 deg, 4 s for a +-15 km window, on a
// 200 MHz Pentium Pro). Needs ../shared/dem; skips with a message without it.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>

#include "dem/terrain.h"
#include "horizon/horizon.h"
#include "testing/shared_data.h"

namespace horizonreg {
namespace {

struct Case {
  const char* file;
  double lat, lon;
};
// The centres of a 3" tile (1201 x 1201) and of the 1" SRTM tile (3601 x 3601).
constexpr Case kTile3 = {"mt_rainier_90m.tif", 46.5, -121.5};
constexpr Case kTile1 = {"N48W125.hgt", 48.5, -124.5};

std::string DemPath(const char* file) {
  const auto shared = testing::SharedDir();
  return shared ? (*shared / "dem" / file).string() : std::string();
}

void RunHorizon(benchmark::State& state, const Case& c, double max_distance_m, int threads) {
  const std::string path = DemPath(c.file);
  if (path.empty()) {
    state.SkipWithError("../shared is absent");
    return;
  }
  HorizonOptions o;
  o.max_distance_m = max_distance_m;
  o.num_threads = threads;
  const Terrain terrain({path});
  const TerrainWindow w = terrain.ReadWindow({c.lat, c.lon, 0}, o.max_distance_m);
  const GeodeticPoint obs = ResolveObserver(w, c.lat, c.lon, 1.7, std::nullopt);
  size_t posts = 0;
  for (const auto& g : w.grids) posts += g.height_m.size();
  for (auto _ : state) benchmark::DoNotOptimize(ComputeHorizon(w, obs, o));
  state.counters["posts"] = static_cast<double>(posts);
}

void BM_Horizon_FullTile3arcsec(benchmark::State& s) { RunHorizon(s, kTile3, 100'000, static_cast<int>(s.range(0))); }
void BM_Horizon_Window15km(benchmark::State& s) { RunHorizon(s, kTile3, 15'000, static_cast<int>(s.range(0))); }
void BM_Horizon_FullTile1arcsec(benchmark::State& s) { RunHorizon(s, kTile1, 100'000, static_cast<int>(s.range(0))); }

void BM_Ridges_FullTile3arcsec(benchmark::State& state) {
  const std::string path = DemPath(kTile3.file);
  if (path.empty()) return state.SkipWithError("../shared is absent");
  HorizonOptions o;
  const Terrain terrain({path});
  const TerrainWindow w = terrain.ReadWindow({kTile3.lat, kTile3.lon, 0}, o.max_distance_m);
  const GeodeticPoint obs = ResolveObserver(w, kTile3.lat, kTile3.lon, 1.7, std::nullopt);
  for (auto _ : state) benchmark::DoNotOptimize(ComputeRidges(w, obs, o, RidgeOptions{}));
}

// A view's horizon (0.1 deg bins over +-40 deg, 40 km, one thread: as the
// position check's places) 600 m from one computed before, without (0) and
// with (1) that one's hints (HorizonHints): the same horizon, the terrain
// under the hints culled sooner.
void BM_Horizon_ViewNearAnother(benchmark::State& state) {
  const std::string path = DemPath(kTile3.file);
  if (path.empty()) return state.SkipWithError("../shared is absent");
  HorizonOptions o;
  o.azimuth_step_deg = 0.1;
  o.max_distance_m = 40'000;
  o.num_threads = 1;
  o.sector_center_deg = 60.0;
  o.sector_half_width_deg = 40.0;
  const Terrain terrain({path});
  const TerrainWindow w = terrain.ReadWindow({kTile3.lat, kTile3.lon, 0}, 45'000);
  const GeodeticPoint a = ResolveObserver(w, kTile3.lat, kTile3.lon, 1.7, std::nullopt);
  const GeodeticPoint b = ResolveObserver(w, kTile3.lat + 0.0054, kTile3.lon, 1.7, std::nullopt);  // 600 m north
  const HorizonProfile from_a = ComputeHorizon(w, a, o);
  for (auto _ : state) {
    if (state.range(0))
      benchmark::DoNotOptimize(ComputeHorizonNear(w, b, o, from_a));
    else
      benchmark::DoNotOptimize(ComputeHorizon(w, b, o));
  }
}

void LoadDem(benchmark::State& state, const Case& c) {
  const std::string path = DemPath(c.file);
  if (path.empty()) return state.SkipWithError("../shared is absent");
  for (auto _ : state) {
    const Terrain terrain({path});
    benchmark::DoNotOptimize(terrain.ReadWindow({c.lat, c.lon, 0}, 100'000));
  }
}
void BM_LoadDem_Tile3arcsec(benchmark::State& s) { LoadDem(s, kTile3); }
void BM_LoadDem_Tile1arcsec(benchmark::State& s) { LoadDem(s, kTile1); }

BENCHMARK(BM_Horizon_FullTile3arcsec)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Horizon_Window15km)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Horizon_FullTile1arcsec)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Ridges_FullTile3arcsec)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Horizon_ViewNearAnother)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_LoadDem_Tile3arcsec)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_LoadDem_Tile1arcsec)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace horizonreg

int main(int argc, char** argv) {
  std::printf(
      "Paper (Behringer 1999, 200 MHz Pentium Pro): full 1201x1201 tile at 0.25 deg 40 s; +-15 km window 4 s.\n");
  if (!horizonreg::testing::SharedDir()) std::printf("SKIPPED: ../shared is absent; the benchmarks need its DEMs.\n");
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
