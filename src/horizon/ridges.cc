// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>

#include "horizon/horizon.h"
#include "horizon/sweep.h"

namespace horizonreg {
namespace {

using internal::SweepPoint;
using internal::SweepSetup;

struct RaySample {
  float d;
  float tan_el;
};

// Collects, per bin-centre ray, where the bilinear surface crosses it.
class RayCollector {
 public:
  explicit RayCollector(const SweepSetup& setup) : setup_(&setup), rays_(setup.num_sectors) {}
  void Post(const SweepPoint&) {}
  void Quad(const SweepPoint&, const SweepPoint&, const SweepPoint&, const SweepPoint&) {}
  void Edge(const SweepPoint& p, const SweepPoint& q) {
    if (p.sector == q.sector) return;
    internal::WalkCrossings(*setup_, p, q, [&](int ray, double t, int, int) {
      const SweepPoint x = internal::Lerp(p, q, t);
      rays_[ray].push_back({static_cast<float>(x.d), static_cast<float>(x.tan_el)});
    });
  }
  std::vector<std::vector<RaySample>>& rays() { return rays_; }

 private:
  const SweepSetup* setup_;
  std::vector<std::vector<RaySample>> rays_;
};

}  // namespace

std::vector<std::vector<Ridge>> ComputeRidges(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                              const HorizonOptions& options, const RidgeOptions& ridge_options) {
  options.Check();
  ridge_options.Check();
  const LocalFrame frame(observer);
  const int n = options.NumBins();
  // Rays at bin centres: sector s lies between centre rays s and s + 1.
  const SweepSetup setup =
      internal::MakeSweepSetup(n, 0.0, options.min_distance_m, options.max_distance_m, options.refraction);
  auto collectors = internal::SweepGrids<RayCollector>(terrain.grids, frame, setup, options.pool, options.num_threads,
                                                       [&] { return RayCollector(setup); });
  double spacing = 0.0;
  for (const DemGrid& g : terrain.grids) spacing = std::max(spacing, g.SpacingM());

  std::vector<std::vector<Ridge>> out(n);
  std::vector<RaySample> ray;
  for (int i = 0; i < n; ++i) {
    ray.clear();
    for (auto& c : collectors) ray.insert(ray.end(), c.rays()[i].begin(), c.rays()[i].end());
    std::sort(ray.begin(), ray.end(), [](const RaySample& a, const RaySample& b) {
      return a.d < b.d || (a.d == b.d && a.tan_el < b.tan_el);
    });
    // Visible local maxima: points above everything nearer, followed by terrain
    // that stays below them for a while.
    std::vector<Ridge> found;
    float running_max = -INFINITY;
    for (size_t k = 0; k < ray.size(); ++k) {
      if (ray[k].tan_el <= running_max) continue;
      running_max = ray[k].tan_el;
      if (ray[k].d < ridge_options.min_distance_spacings * spacing) continue;
      // How far behind k the terrain stays below it.
      size_t j = k + 1;
      while (j < ray.size() && ray[j].tan_el <= ray[k].tan_el) ++j;
      if (j == k + 1) continue;    // the terrain keeps rising: not a silhouette
      if (j == ray.size()) break;  // nothing behind rises above it: the outer horizon
      const double depth = ray[j].d - ray[k].d;
      if (depth >= ridge_options.min_depth_ratio * ray[k].d && depth >= ridge_options.min_depth_spacings * spacing)
        found.push_back({RadToDeg(std::atan(static_cast<double>(ray[k].tan_el))), ray[k].d});
    }
    // Highest (farthest) first; drop ridges hugging the silhouette above them.
    double above = RadToDeg(std::atan(static_cast<double>(running_max)));
    for (auto it = found.rbegin(); it != found.rend(); ++it) {
      if (above - it->elevation_deg >= ridge_options.min_separation_deg) {
        out[i].push_back(*it);
        above = it->elevation_deg;
      }
    }
  }
  return out;
}

}  // namespace horizonreg
