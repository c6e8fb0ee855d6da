// SPDX-License-Identifier: MIT
// Internal: the pass over DEM posts and grid edges shared by the horizon and
// the ridge lines. Not a public header.
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "dem/dem_grid.h"
#include "geo/geodesy.h"
#include "util/fast_math.h"
#include "util/thread_pool.h"

namespace horizonreg::internal {

// A post (or a point on a grid edge) in the observer's frame.
struct SweepPoint {
  double e = 0, n = 0;  // horizontal ENU position, m
  double u = 0;         // ENU up (geometric, no refraction), m
  double w = 0;         // u + refraction lift, m
  double d = 0;         // horizontal distance, m
  double tan_el = 0;    // w / d
  double h = 0;         // DEM height, m
  int sector = -1;      // -1: not valid (void, too near or too far)
};

struct SweepSetup {
  int num_sectors = 0;       // number of rays = sectors
  double step_rad = 0;       // angular spacing
  double sector_offset = 0;  // sector s covers azimuths [(s - o) step, (s + 1 - o) step)
  double min_distance_m = 0;
  double max_distance_m = 0;
  double refraction = 0;
  std::vector<double> ray_sin, ray_cos;  // ray b (boundary between sectors b-1 and b) at (b - o) step
};

inline SweepSetup MakeSweepSetup(int num_sectors, double offset, double min_d, double max_d, double k) {
  SweepSetup s;
  s.num_sectors = num_sectors;
  s.step_rad = 2.0 * kPi / num_sectors;
  s.sector_offset = offset;
  s.min_distance_m = min_d;
  s.max_distance_m = max_d;
  s.refraction = k;
  s.ray_sin.resize(num_sectors);
  s.ray_cos.resize(num_sectors);
  for (int b = 0; b < num_sectors; ++b) {
    const double az = (b - offset) * s.step_rad;
    s.ray_sin[b] = std::sin(az);
    s.ray_cos[b] = std::cos(az);
  }
  return s;
}

// Point at parameter t on the edge from p to q (linear in e, n, u, w, h).
inline SweepPoint Lerp(const SweepPoint& p, const SweepPoint& q, double t) {
  SweepPoint x;
  x.e = p.e + t * (q.e - p.e);
  x.n = p.n + t * (q.n - p.n);
  x.u = p.u + t * (q.u - p.u);
  x.w = p.w + t * (q.w - p.w);
  x.h = p.h + t * (q.h - p.h);
  x.d = std::sqrt(x.e * x.e + x.n * x.n);
  x.tan_el = x.w / x.d;
  return x;
}

// One row of posts to place in the observer's frame (see ComputeRow).
struct RowInput {
  double obs_sin_lat, obs_cos_lat, obs_x, obs_z;       // observer, in the frame rotated to its meridian
  double row_sin_lat = 0, row_cos_lat = 0, row_n = 0;  // separable grids: the row's latitude
  const double* post_sin_lat = nullptr;                // non-separable grids: per post (then row_* unused)
  const double* post_cos_lat = nullptr;
  const double* col_sin_dlon = nullptr;  // sin / cos of (post longitude - observer longitude)
  const double* col_cos_dlon = nullptr;
  const float* heights = nullptr;
  int count = 0, stride = 1;
  double inv_step = 0, sector_offset = 0, lift_scale = 0, min_d2 = 0, max_d2 = 0;
  int num_sectors = 0;
};

// Structure-of-arrays results of ComputeRow, one entry per post of the row.
struct RowScratch {
  explicit RowScratch(int size)
      : e(size),
        n(size),
        u(size),
        w(size),
        d(size),
        tan_el(size),
        h(size),
        sin_lat(size),
        cos_lat(size),
        sin_dlon(size),
        cos_dlon(size),
        sector(size) {}
  std::vector<double> e, n, u, w, d, tan_el, h, sin_lat, cos_lat, sin_dlon, cos_dlon;
  std::vector<int> sector;  // -1: not valid
};

// Exact ENU (closed-form ECEF rotated to the observer's meridian), refraction
// lift, tan(elevation) and azimuth sector of every stride-th post of a row.
// Branch-free so the compiler vectorises it; built for AVX2 and baseline
// x86-64 with run-time dispatch (horizon/sweep.cc).
void ComputeRow(const RowInput& in, RowScratch& out);

// Calls handler.Post(p) for every valid post, handler.Edge(p, q) for every
// grid edge between two valid posts, and handler.Quad(a, b, c, d) for every
// cell with four valid corners (a, b on the northern row west to east, c, d
// below them). Rows [row_begin, row_end) of `grid`; the row before row_begin
// is computed for the edges and cells that join it. With pre_pass, only a
// sparse subset of the posts goes to handler.Post (see below).
template <typename Handler>
void SweepRows(const DemGrid& grid, const LocalFrame& frame, const SweepSetup& setup, int row_begin, int row_end,
               bool pre_pass, Handler& handler) {
  const GeodeticPoint& o = frame.origin();
  const double sp0 = std::sin(DegToRad(o.lat_deg)), cp0 = std::cos(DegToRad(o.lat_deg));
  const double n0 = kWgs84A / std::sqrt(1.0 - kWgs84E2 * sp0 * sp0);
  const double x0 = (n0 + o.height_m) * cp0, z0 = (n0 * (1.0 - kWgs84E2) + o.height_m) * sp0;
  const int w = grid.width;
  std::vector<double> col_s, col_c;  // sin / cos of (lon - lon0), separable grids
  if (grid.separable) {
    col_s.resize(w);
    col_c.resize(w);
    for (int c = 0; c < w; ++c) {
      const double dl = DegToRad(grid.lon0_deg + c * grid.dlon_deg - o.lon_deg);
      col_s[c] = std::sin(dl);
      col_c[c] = std::cos(dl);
    }
  }
  const double inv_step = 1.0 / setup.step_rad;
  const double lift_scale = setup.refraction / (2.0 * kRefractionEarthRadiusM);
  const double min_d2 = setup.min_distance_m * setup.min_distance_m;
  const double max_d2 = setup.max_distance_m * setup.max_distance_m;

  RowScratch scratch(w);
  auto compute_row = [&](int r, std::vector<SweepPoint>& row, int col_stride = 1) {
    RowInput in;
    in.obs_sin_lat = sp0, in.obs_cos_lat = cp0, in.obs_x = x0, in.obs_z = z0;
    in.inv_step = inv_step, in.sector_offset = setup.sector_offset, in.num_sectors = setup.num_sectors;
    in.lift_scale = lift_scale, in.min_d2 = min_d2, in.max_d2 = max_d2;
    in.heights = grid.height_m.data() + static_cast<size_t>(r) * w;
    in.count = w;
    in.stride = col_stride;
    if (grid.separable) {
      const double lat = DegToRad(grid.lat0_deg + r * grid.dlat_deg);
      in.row_sin_lat = std::sin(lat), in.row_cos_lat = std::cos(lat);
      in.row_n = kWgs84A / std::sqrt(1.0 - kWgs84E2 * in.row_sin_lat * in.row_sin_lat);
      in.col_sin_dlon = col_s.data(), in.col_cos_dlon = col_c.data();
    } else {
      for (int c = 0; c < w; ++c) {
        const size_t k = static_cast<size_t>(r) * w + c;
        const double lat = DegToRad(grid.lat_deg[k]), dl = DegToRad(grid.lon_deg[k] - o.lon_deg);
        scratch.sin_lat[c] = std::sin(lat), scratch.cos_lat[c] = std::cos(lat);
        scratch.sin_dlon[c] = std::sin(dl), scratch.cos_dlon[c] = std::cos(dl);
      }
      in.post_sin_lat = scratch.sin_lat.data(), in.post_cos_lat = scratch.cos_lat.data();
      in.col_sin_dlon = scratch.sin_dlon.data(), in.col_cos_dlon = scratch.cos_dlon.data();
    }
    ComputeRow(in, scratch);
    for (int c = 0; c < w; c += col_stride) {
      SweepPoint& p = row[c];
      p.sector = scratch.sector[c];
      if (p.sector < 0) continue;
      p.e = scratch.e[c], p.n = scratch.n[c], p.u = scratch.u[c], p.w = scratch.w[c];
      p.d = scratch.d[c], p.tan_el = scratch.tan_el[c], p.h = in.heights[c];
    }
  };

  std::vector<SweepPoint> prev(w), cur(w);
  if (pre_pass) {
    // Every kPrePassStride-th post of every kPrePassStride-th row, so the
    // handler holds a good lower bound of each sector's maximum before the
    // full pass and can skip the edges and cells that cannot raise it.
    constexpr int kPrePassStride = 4;
    for (int r = row_begin; r < row_end; r += kPrePassStride) {
      compute_row(r, cur, kPrePassStride);
      for (int c = 0; c < w; c += kPrePassStride)
        if (cur[c].sector >= 0) handler.Post(cur[c]);
    }
    return;
  }
  if (row_begin > 0) compute_row(row_begin - 1, prev);
  for (int r = row_begin; r < row_end; ++r) {
    compute_row(r, cur);
    for (int c = 0; c < w; ++c) {
      const SweepPoint& p = cur[c];
      if (p.sector < 0) continue;
      handler.Post(p);
      if (c + 1 < w && cur[c + 1].sector >= 0) handler.Edge(p, cur[c + 1]);
      if (r > 0 && prev[c].sector >= 0) handler.Edge(prev[c], p);
      if (r > 0 && c + 1 < w && prev[c].sector >= 0 && prev[c + 1].sector >= 0 && cur[c + 1].sector >= 0)
        handler.Quad(prev[c], prev[c + 1], p, cur[c + 1]);
    }
    std::swap(prev, cur);
  }
}

// Walks the rays an edge p -> q crosses, in order, calling
// visit(ray_index, t, sector_before, sector_after). Returns false when the
// edge passes (nearly) through the observer and was not walked.
template <typename Visit>
bool WalkCrossings(const SweepSetup& setup, const SweepPoint& p, const SweepPoint& q, Visit&& visit) {
  const int n = setup.num_sectors;
  const double cross = p.e * q.n - p.n * q.e;
  if (cross == 0.0) return false;
  const int dir = cross < 0.0 ? 1 : -1;  // +1: azimuth increases from p to q
  int count = dir > 0 ? q.sector - p.sector : p.sector - q.sector;
  if (count < 0) count += n;
  if (count >= n / 2 + 1) return false;  // inconsistent (edge at the observer)
  const double ve = q.e - p.e, vn = q.n - p.n;
  int s = p.sector;
  for (int i = 0; i < count; ++i) {
    const int next = dir > 0 ? (s + 1 == n ? 0 : s + 1) : (s == 0 ? n - 1 : s - 1);
    const int ray = dir > 0 ? next : s;
    const double ue = setup.ray_sin[ray], un = setup.ray_cos[ray];
    const double denom = ue * vn - un * ve;
    double t = denom != 0.0 ? -(ue * p.n - un * p.e) / denom : 0.5;
    t = std::clamp(t, 0.0, 1.0);
    visit(ray, t, s, next);
    s = next;
  }
  return true;
}

// The rays crossing a cell with corners a, b, c, d: calls visit(ray,
// sector_before, sector_after) for each. Returns false when the cell
// surrounds the observer (it spans more than half the circle).
template <typename Visit>
bool CellRays(const SweepSetup& setup, const SweepPoint& a, const SweepPoint& b, const SweepPoint& c,
              const SweepPoint& d, Visit&& visit) {
  const int n = setup.num_sectors, half = n / 2;
  auto rel = [&](int s) {
    int k = s - a.sector;
    if (k > half) k -= n;
    if (k < -half) k += n;
    return k;
  };
  const int kb = rel(b.sector), kc = rel(c.sector), kd = rel(d.sector);
  const int lo = std::min({0, kb, kc, kd}), hi = std::max({0, kb, kc, kd});
  if (hi - lo >= half) return false;
  for (int k = lo + 1; k <= hi; ++k) {
    int after = a.sector + k;
    after = ((after % n) + n) % n;
    const int before = after == 0 ? n - 1 : after - 1;
    visit(after, before, after);
  }
  return true;
}

// Runs a sweep over every grid on `pool` (or on a pool of `num_threads`
// made for the call when it is null), one handler per pool slot, made by
// make_handler(); returns the handlers for merging. Rows go out in blocks,
// so voids and far areas do not leave a thread idle; a handler first runs
// the sparse pre-pass over the whole grid. The merged result must not
// depend on which handler saw which block (handlers break ties by position,
// not by order).
template <typename Handler, typename Make>
std::vector<Handler> SweepGrids(const std::vector<DemGrid>& grids, const LocalFrame& frame, const SweepSetup& setup,
                                ThreadPool* pool, int num_threads, Make&& make_handler) {
  std::optional<ThreadPool> own;
  if (!pool && num_threads > 1) pool = &own.emplace(num_threads);
  const int slots = pool ? pool->size() : 1;
  std::vector<Handler> handlers;
  for (int i = 0; i < slots; ++i) handlers.push_back(make_handler());
  constexpr int kBlockRows = 32;
  for (const DemGrid& grid : grids) {
    if (grid.width < 2 || grid.height < 2) continue;
    const int blocks = (grid.height + kBlockRows - 1) / kBlockRows;
    std::vector<char> primed(slots, 0);
    ParallelFor(pool, static_cast<size_t>(blocks), [&](size_t b, int t) {
      if (!primed[t]) {
        SweepRows(grid, frame, setup, 0, grid.height, true, handlers[t]);
        primed[t] = 1;
      }
      const int r0 = static_cast<int>(b) * kBlockRows;
      SweepRows(grid, frame, setup, r0, std::min(grid.height, r0 + kBlockRows), false, handlers[t]);
    });
  }
  return handlers;
}

}  // namespace horizonreg::internal
