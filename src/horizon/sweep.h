// SPDX-License-Identifier: MIT
// Internal: the pass over DEM posts and grid edges shared by the horizon and
// the ridge lines. Not a public header.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
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

// The trigonometry of a separable grid's posts: sin (first width values)
// and cos (next width) of (column longitude - lon0), then sin and cos of
// each row's latitude and its prime-vertical radius (height values each).
inline std::vector<double> GridTrig(const DemGrid& grid, double lon0_deg) {
  const size_t w = grid.width, h = grid.height;
  std::vector<double> t(2 * w + 3 * h);
  for (size_t c = 0; c < w; ++c) {
    const double dl = DegToRad(grid.lon0_deg + static_cast<double>(c) * grid.dlon_deg - lon0_deg);
    t[c] = std::sin(dl);
    t[w + c] = std::cos(dl);
  }
  for (size_t r = 0; r < h; ++r) {
    const double lat = DegToRad(grid.lat0_deg + static_cast<double>(r) * grid.dlat_deg), sp = std::sin(lat);
    t[2 * w + r] = sp;
    t[2 * w + h + r] = std::cos(lat);
    t[2 * w + 2 * h + r] = kWgs84A / std::sqrt(1.0 - kWgs84E2 * sp * sp);
  }
  return t;
}

// Calls handler.Post(p) for every valid post, handler.Edge(p, q) for every
// grid edge between two valid posts, and handler.Quad(a, b, c, d) for every
// cell with four valid corners (a, b on the northern row west to east, c, d
// below them). Rows [row_begin, row_end) of `grid`; the row before row_begin
// is computed for the edges and cells that join it. With pre_pass, only a
// sparse subset of the posts goes to handler.Post (see below).
template <typename Handler>
void SweepRows(const DemGrid& grid, const LocalFrame& frame, const SweepSetup& setup, int row_begin, int row_end,
               bool pre_pass, Handler& handler, const std::vector<double>* grid_trig = nullptr) {
  const GeodeticPoint& o = frame.origin();
  const double sp0 = std::sin(DegToRad(o.lat_deg)), cp0 = std::cos(DegToRad(o.lat_deg));
  const double n0 = kWgs84A / std::sqrt(1.0 - kWgs84E2 * sp0 * sp0);
  const double x0 = (n0 + o.height_m) * cp0, z0 = (n0 * (1.0 - kWgs84E2) + o.height_m) * sp0;
  const int w = grid.width;
  // Separable grids: sin / cos of (lon - lon0) per column, sin / cos of the
  // latitude and the prime-vertical radius per row (GridTrig, or computed here).
  std::vector<double> own_trig;
  if (grid.separable && grid_trig == nullptr) own_trig = GridTrig(grid, o.lon_deg);
  const double* col_s = grid.separable ? (grid_trig ? grid_trig : &own_trig)->data() : nullptr;
  const double* col_c = grid.separable ? col_s + w : nullptr;
  const double* row_s = grid.separable ? col_s + 2 * static_cast<size_t>(w) : nullptr;
  const double* row_c = grid.separable ? row_s + grid.height : nullptr;
  const double* row_nr = grid.separable ? row_c + grid.height : nullptr;
  const double inv_step = 1.0 / setup.step_rad;
  const double lift_scale = setup.refraction / (2.0 * kRefractionEarthRadiusM);
  const double min_d2 = setup.min_distance_m * setup.min_distance_m;
  const double max_d2 = setup.max_distance_m * setup.max_distance_m;

  // Non-separable grids: the posts' own sines and cosines when indexed.
  const bool cached_trig =
      !grid.separable && grid.post_trig.size() == 4 * static_cast<size_t>(w) * static_cast<size_t>(grid.height);
  const double sin_lon0 = std::sin(DegToRad(o.lon_deg)), cos_lon0 = std::cos(DegToRad(o.lon_deg));
  // Per thread, kept from call to call (a sweep makes one call per block of
  // rows): allocating and zeroing them each time cost 3% of a position
  // check. Only the columns a call computes are read back.
  thread_local RowScratch scratch(0);
  if (static_cast<int>(scratch.e.size()) < w) scratch = RowScratch(w);
  // Places the posts of row r, columns [c_begin, c_end) (every col_stride-th).
  auto compute_row = [&](int r, std::vector<SweepPoint>& row, int col_stride = 1, int c_begin = 0, int c_end = -1) {
    if (c_end < 0) c_end = w;
    RowInput in;
    in.obs_sin_lat = sp0, in.obs_cos_lat = cp0, in.obs_x = x0, in.obs_z = z0;
    in.inv_step = inv_step, in.sector_offset = setup.sector_offset, in.num_sectors = setup.num_sectors;
    in.lift_scale = lift_scale, in.min_d2 = min_d2, in.max_d2 = max_d2;
    in.heights = grid.height_m.data() + static_cast<size_t>(r) * w + c_begin;
    in.count = c_end - c_begin;
    in.stride = col_stride;
    if (grid.separable) {
      in.row_sin_lat = row_s[r], in.row_cos_lat = row_c[r], in.row_n = row_nr[r];
      in.col_sin_dlon = col_s + c_begin, in.col_cos_dlon = col_c + c_begin;
    } else {
      if (cached_trig) {
        for (int c = c_begin; c < c_end; c += col_stride) {  // ComputeRow reads every col_stride-th
          const double* t = grid.post_trig.data() + 4 * (static_cast<size_t>(r) * w + c);
          scratch.sin_lat[c - c_begin] = t[0], scratch.cos_lat[c - c_begin] = t[1];
          scratch.sin_dlon[c - c_begin] = t[2] * cos_lon0 - t[3] * sin_lon0;
          scratch.cos_dlon[c - c_begin] = t[3] * cos_lon0 + t[2] * sin_lon0;
        }
      } else {
        for (int c = c_begin; c < c_end; c += col_stride) {
          const size_t k = static_cast<size_t>(r) * w + c;
          const double lat = DegToRad(grid.lat_deg[k]), dl = DegToRad(grid.lon_deg[k] - o.lon_deg);
          scratch.sin_lat[c - c_begin] = std::sin(lat), scratch.cos_lat[c - c_begin] = std::cos(lat);
          scratch.sin_dlon[c - c_begin] = std::sin(dl), scratch.cos_dlon[c - c_begin] = std::cos(dl);
        }
      }
      in.post_sin_lat = scratch.sin_lat.data(), in.post_cos_lat = scratch.cos_lat.data();
      in.col_sin_dlon = scratch.sin_dlon.data(), in.col_cos_dlon = scratch.cos_dlon.data();
    }
    ComputeRow(in, scratch);
    for (int i = 0; i < in.count; i += col_stride) {
      SweepPoint& p = row[c_begin + i];
      p.sector = scratch.sector[i];
      if (p.sector < 0) continue;
      p.e = scratch.e[i], p.n = scratch.n[i], p.u = scratch.u[i], p.w = scratch.w[i];
      p.d = scratch.d[i], p.tan_el = scratch.tan_el[i], p.h = in.heights[i];
    }
  };

  thread_local std::vector<SweepPoint> prev_rows, cur_rows;
  if (static_cast<int>(prev_rows.size()) < w) prev_rows.resize(w), cur_rows.resize(w);
  std::vector<SweepPoint>& prev = prev_rows;
  std::vector<SweepPoint>& cur = cur_rows;
  if (pre_pass) {
    // Every kPrePassStride-th post of every kPrePassStride-th row, so the
    // handler holds a good lower bound of each sector's maximum before the
    // full pass and can skip the edges, cells and tiles that cannot raise it.
    constexpr int kPrePassStride = 4;
    for (int r = row_begin; r < row_end; r += kPrePassStride) {
      compute_row(r, cur, kPrePassStride);
      for (int c = 0; c < w; c += kPrePassStride)
        if (cur[c].sector >= 0) handler.Post(cur[c]);
    }
    return;
  }
  // The rows go out in tiles of kTileCols columns (plus the next tile's first
  // column, for the edges and cells that join them). A handler that reports
  // its sectors' current maxima (LowestBest) lets a tile be skipped when no
  // point on it, posts, edges or cells, can reach them: bounded above by the
  // tile's highest post at its nearest distance (conservatively: the earth's
  // curvature drop at 95%, the refraction lift at the farthest distance, 1 m
  // to spare), over its azimuth span plus a sector each side. The bound is
  // strict, so the result (ties included) is that of the full pass.
  constexpr int kTileCols = DemGrid::kBlock;
  constexpr bool kCanCull = requires(const Handler& h) { h.LowestBest(0, 1); };
  // Horizontal ENU position of post (c, r) at height 0 (as ComputeRow places
  // posts; the tile tests need no more).
  const auto enu_of = [&](int c, int r) {
    if (!grid.separable) {
      const size_t k = static_cast<size_t>(r) * w + c;
      return Eigen::Vector2d(frame.EnuFromGeodetic({grid.lat_deg[k], grid.lon_deg[k], 0.0}).head<2>());
    }
    const double sp = row_s[r], nr = row_nr[r];
    const double a = nr * row_c[r];
    const double dx = a * col_c[c] - x0, dz = nr * (1.0 - kWgs84E2) * sp - z0;
    return Eigen::Vector2d(a * col_s[c], -sp0 * dx + cp0 * dz);
  };
  // Whether no point of the tile of rows [r0, r1) (and the row above) and
  // columns [c0, c1] can reach the handler's current maxima, its highest
  // post being hmax.
  const auto tile_skipped = [&](int r0, int r1, int c0, int c1, float hmax) -> bool {
    if constexpr (!kCanCull) {
      return false;
    } else {
      if (!(hmax > -std::numeric_limits<float>::infinity())) return true;  // all void
      const int rf = r0 > 0 ? r0 - 1 : r0;
      const Eigen::Vector2d corner[4] = {enu_of(c0, rf), enu_of(c1, rf), enu_of(c1, r1 - 1), enu_of(c0, r1 - 1)};
      // Distance from the observer (0, 0) to the quadrilateral, and its farthest corner.
      double d_min = std::numeric_limits<double>::infinity(), d_max = 0.0;
      double cross_sign = 0.0;
      bool inside = true;
      for (int i = 0; i < 4; ++i) {
        const Eigen::Vector2d a = corner[i], b = corner[(i + 1) % 4], ab = b - a;
        const double t = std::clamp(-a.dot(ab) / std::max(1e-12, ab.squaredNorm()), 0.0, 1.0);
        d_min = std::min(d_min, (a + t * ab).norm());
        d_max = std::max(d_max, a.norm());
        const double cr = a.x() * ab.y() - a.y() * ab.x();
        if (cross_sign == 0.0) cross_sign = cr;
        inside = inside && cr * cross_sign > 0.0;
      }
      const double margin = 2.0 + 0.001 * d_min;
      d_min -= margin;
      d_max += margin;
      if (inside || d_min <= 0.0) return false;
      if (d_min > setup.max_distance_m) return true;  // every post too far
      // The azimuth span of the corners (the tile spans less than half a turn).
      const double a0 = std::atan2(corner[0].x(), corner[0].y());
      double lo = 0.0, hi = 0.0;
      for (int i = 1; i < 4; ++i) {
        double da = std::atan2(corner[i].x(), corner[i].y()) - a0;
        da -= 2.0 * kPi * std::round(da / (2.0 * kPi));
        lo = std::min(lo, da), hi = std::max(hi, da);
      }
      if (hi - lo >= kPi) return false;
      double az_lo = a0 + lo;
      az_lo -= 2.0 * kPi * std::floor(az_lo / (2.0 * kPi));
      const int n = setup.num_sectors;
      const int first = static_cast<int>(std::floor(az_lo * inv_step + setup.sector_offset)) - 1;
      const int count = static_cast<int>(std::ceil((hi - lo) * inv_step)) + 3;
      if (count >= n) return false;
      const double drop = 0.95 * d_min * d_min / (2.0 * 6.40e6);
      const double w_bound = (hmax - o.height_m) - drop + lift_scale * d_max * d_max + 1.0;
      const double tan_bound = w_bound >= 0.0 ? w_bound / d_min : w_bound / d_max;
      return tan_bound < handler.LowestBest(((first % n) + n) % n, count);
    }
  };
  // The posts, edges and cells of rows [r0, r1) and columns [c0, c1) (the
  // posts of column c1 too when it is the grid's last).
  const auto process = [&](int r0, int r1, int c0, int c1) {
    const bool last = c1 == w - 1;
    if (r0 > 0) compute_row(r0 - 1, prev, 1, c0, c1 + 1);
    for (int r = r0; r < r1; ++r) {
      compute_row(r, cur, 1, c0, c1 + 1);
      for (int c = c0; c < (last ? c1 + 1 : c1); ++c) {
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
  };
  const auto max_of = [&](int r0, int r1, int c0, int c1) {
    if (const float* m = grid.BlockMax(r0, r1, c0, c1)) return *m;
    float m = -std::numeric_limits<float>::infinity();
    for (int r = r0 > 0 ? r0 - 1 : r0; r < r1; ++r) {
      const float* row = grid.height_m.data() + static_cast<size_t>(r) * w;
      for (int c = c0; c <= c1; ++c) m = row[c] > m ? row[c] : m;  // NaN (void) posts are skipped
    }
    return m;
  };
  // A tile that cannot be skipped is split in four, down to kMinTile posts.
  constexpr int kMinTile = 8;
  const auto visit = [&](auto&& self, int r0, int r1, int c0, int c1, float hmax) -> void {
    if (tile_skipped(r0, r1, c0, c1, hmax)) return;
    if (!kCanCull || (r1 - r0 <= kMinTile && c1 - c0 <= kMinTile)) return process(r0, r1, c0, c1);
    const int rm = r1 - r0 > kMinTile ? r0 + (r1 - r0) / 2 : r1, cm = c1 - c0 > kMinTile ? c0 + (c1 - c0) / 2 : c1;
    const int rows[3] = {r0, rm, r1}, cols[3] = {c0, cm, c1};
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j)
        if (rows[i] < rows[i + 1] && cols[j] < cols[j + 1])
          self(self, rows[i], rows[i + 1], cols[j], cols[j + 1], max_of(rows[i], rows[i + 1], cols[j], cols[j + 1]));
  };
  for (int c0 = 0; c0 < w - 1; c0 += kTileCols) {
    const int c1 = std::min(w - 1, c0 + kTileCols);  // inclusive: the next tile's first column
    const float hmax = kCanCull ? max_of(row_begin, row_end, c0, c1) : 0.0f;
    visit(visit, row_begin, row_end, c0, c1, hmax);
  }
}

// The rays an edge p -> q crosses: the way its azimuth turns from p to q
// (dir +1: increasing) and how many (count); nullopt when the edge passes
// (nearly) through the observer and is not walked.
struct CrossingWalk {
  int dir = 1, count = 0;
};
inline std::optional<CrossingWalk> WalkOf(const SweepSetup& setup, const SweepPoint& p, const SweepPoint& q) {
  const int n = setup.num_sectors;
  const double cross = p.e * q.n - p.n * q.e;
  if (cross == 0.0) return std::nullopt;
  const int dir = cross < 0.0 ? 1 : -1;
  int count = dir > 0 ? q.sector - p.sector : p.sector - q.sector;
  if (count < 0) count += n;
  if (count >= n / 2 + 1) return std::nullopt;  // inconsistent (edge at the observer)
  return CrossingWalk{dir, count};
}

// Walks the rays an edge p -> q crosses, in order, calling
// visit(ray_index, t, sector_before, sector_after). Returns false when the
// edge passes (nearly) through the observer and was not walked.
template <typename Visit>
bool WalkCrossings(const SweepSetup& setup, const SweepPoint& p, const SweepPoint& q, Visit&& visit) {
  const std::optional<CrossingWalk> walk = WalkOf(setup, p, q);
  if (!walk) return false;
  const int n = setup.num_sectors, dir = walk->dir, count = walk->count;
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
  constexpr int kBlockRows = DemGrid::kBlock;  // the tiles of DemGrid::block_max
  for (const DemGrid& grid : grids) {
    if (grid.width < 2 || grid.height < 2) continue;
    const int blocks = (grid.height + kBlockRows - 1) / kBlockRows;
    const std::vector<double> trig = grid.separable ? GridTrig(grid, frame.origin().lon_deg) : std::vector<double>();
    std::vector<char> primed(slots, 0);
    ParallelFor(pool, static_cast<size_t>(blocks), [&](size_t b, int t) {
      if (!primed[t]) {
        SweepRows(grid, frame, setup, 0, grid.height, true, handlers[t], &trig);
        primed[t] = 1;
      }
      const int r0 = static_cast<int>(b) * kBlockRows;
      SweepRows(grid, frame, setup, r0, std::min(grid.height, r0 + kBlockRows), false, handlers[t], &trig);
    });
  }
  return handlers;
}

}  // namespace horizonreg::internal
