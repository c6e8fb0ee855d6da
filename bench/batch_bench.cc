// SPDX-License-Identifier: MIT
// Throughput of a camera network's archive (issue 8): photos of one station
// registered once its Site is built, as `horizonreg batch` and the Python
// module run them: decode the JPEG, extract the skyline, register, on one
// shared pool of 1 or 2 threads, photos in parallel. And the start-up of a
// station (DEM window and 0.1-deg horizon), and `--refine-position`'s
// position refinement of one registered photo (issue 15: under 1 s). Needs
// ../shared; skips with a message without it.
#include <benchmark/benchmark.h>

#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "pipeline/image_io.h"
#include "pipeline/position.h"
#include "pipeline/register_photo.h"
#include "pipeline/site.h"
#include "testing/shared_data.h"

namespace horizonreg {
namespace {

struct Station {
  std::string image;
  std::vector<std::string> dem;
  double lat, lon;
  SiteOptions options;
};

// A dev scene (rendered, 1024 x 683) or a real photo (968 x 648) as a fixed camera.
std::optional<Station> Load(const std::string& set, const std::string& name) {
  const auto shared = testing::SharedDir();
  if (!shared) return std::nullopt;
  const auto dir = set == "dev" ? *shared / "scenes" / "dev" : *shared / "real" / "columbia";
  const auto t = nlohmann::json::parse(std::ifstream(dir / (name + ".truth.json")));
  Station s{(dir / t["image"].get<std::string>()).string(), {(*shared / "dem" / t["dem"].get<std::string>()).string()},
            t["lat"], t["lon"], {}};
  if (set == "dev")
    s.options.agl_m = t["agl_m"].get<double>();
  else
    s.options.alt_m = t["alt_m"].get<double>();
  return s;
}

void BM_StationStartup(benchmark::State& state, const std::string& set, const std::string& name) {
  const auto st = Load(set, name);
  if (!st) return state.SkipWithError("../shared is absent");
  ThreadPool pool(2);
  for (auto _ : state) benchmark::DoNotOptimize(Site(st->dem, st->lat, st->lon, st->options, &pool).horizon().size());
}

// Argument: threads of the shared pool. 32 photos per iteration.
void BM_PhotosPerSecond(benchmark::State& state, const std::string& set, const std::string& name) {
  const auto st = Load(set, name);
  if (!st) return state.SkipWithError("../shared is absent");
  ThreadPool pool(static_cast<int>(state.range(0)));
  const Site site(st->dem, st->lat, st->lon, st->options, &pool);
  constexpr int kPhotos = 32;
  int registered = 0;
  for (auto _ : state) {
    std::vector<char> ok(kPhotos, 0);
    pool.ParallelFor(kPhotos, [&](size_t i, int) {
      ok[i] = RegisterPhoto(site, ReadImage(st->image), PhotoOptions{}, &pool).registration.registered;
    });
    registered = static_cast<int>(std::count(ok.begin(), ok.end(), 1));
  }
  state.SetItemsProcessed(state.iterations() * kPhotos);
  state.counters["registered_of_32"] = registered;
}

// `--refine-position` for one photo registered beforehand from a position
// 30 m north and 20 m up of the truth (as scripts/eval_position.py gives it):
// the joint fit, the exact horizons at its trial positions and the
// registration again at the estimate (timing_ms.position), on a pool of 2.
void BM_RefinePosition(benchmark::State& state, const std::string& set, const std::string& name) {
  auto st = Load(set, name);
  if (!st) return state.SkipWithError("../shared is absent");
  st->lat += 30.0 / 111'200.0;
  if (st->options.agl_m) *st->options.agl_m += 20.0;
  if (st->options.alt_m) *st->options.alt_m += 20.0;
  ThreadPool pool(2);
  const Site site(st->dem, st->lat, st->lon, st->options, &pool);
  const cv::Mat image = ReadImage(st->image);
  const PhotoRegistration photo = RegisterPhoto(site, image, PhotoOptions{}, &pool);
  if (!(photo.registration.focal_px > 0.0)) return state.SkipWithError("the photo does not register");
  const PositionOptions po = DefaultPositionOptions("arguments", false, std::nullopt);
  int horizons = 0;
  for (auto _ : state) {
    PhotoRegistration out = photo;
    RefinePhotoPosition(site, image, po, photo.options, out, &pool);
    horizons = out.position ? out.position->horizons : 0;
    benchmark::DoNotOptimize(out.registration.pose);
  }
  state.counters["horizons"] = horizons;
}

BENCHMARK_CAPTURE(BM_RefinePosition, dev_rainier_04, std::string("dev"), std::string("rainier_04"))
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RefinePosition, real_AK10, std::string("real"), std::string("AK10_20090803_195410"))
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_StationStartup, dev_alps_03, std::string("dev"), std::string("alps_03"))
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_StationStartup, real_AK10, std::string("real"), std::string("AK10_20090803_195410"))
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_PhotosPerSecond, dev_alps_03, std::string("dev"), std::string("alps_03"))
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_PhotosPerSecond, real_AK10, std::string("real"), std::string("AK10_20090803_195410"))
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace horizonreg

BENCHMARK_MAIN();
