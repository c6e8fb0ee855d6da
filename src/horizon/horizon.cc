// SPDX-License-Identifier: MIT
#include "horizon/horizon.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include "horizon/sweep.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

using internal::SweepPoint;
using internal::SweepSetup;

// Per-bin maxima of one thread.
class HorizonAccumulator {
 public:
  explicit HorizonAccumulator(const SweepSetup& setup) : setup_(&setup), best_(setup.num_sectors) {}
  // Bins outside the sector are never raised (and tiles seen only in them
  // are culled): their maxima start at +infinity.
  // With `hinted`, the bins start at their hints, marked as such (HintLeft).
  HorizonAccumulator(const SweepSetup& setup, const HorizonOptions& options, bool hinted) : HorizonAccumulator(setup) {
    if (hinted)
      for (int i = 0; i < setup.num_sectors; ++i)
        if (std::isfinite((*options.hint_tan_el)[i])) best_[i].tan_el = (*options.hint_tan_el)[i], best_[i].hint = true;
    if (!(options.sector_half_width_deg < 180.0)) return;
    const double step_deg = 360.0 / setup.num_sectors;
    for (int i = 0; i < setup.num_sectors; ++i)
      if (!options.InSector(i * step_deg)) best_[i] = Best{std::numeric_limits<double>::infinity()};
  }

  void Post(const SweepPoint& p) { Update(p.sector, p); }

  void Edge(const SweepPoint& p, const SweepPoint& q) {
    if (p.sector == q.sector) return;
    // Skip edges that cannot raise the sectors at their ends. On the edge
    // w <= w_max and |p| + |q| - length <= 2 r <= 2 max(|p|, |q|), so
    // w / r <= threshold T when w_max <= T r_min: tested without a sqrt.
    if (IsAdjacent(p.sector, q.sector)) {
      const double t = std::min(best_[p.sector].tan_el, best_[q.sector].tan_el);
      const double w_max = std::max(p.w, q.w);
      if (w_max < 0.0) {
        if (w_max <= t * std::max(p.d, q.d)) return;
      } else if (t > 0.0) {
        const double slack = p.d + q.d - 2.0 * w_max / t;  // must exceed the edge length
        const double len2 = (q.e - p.e) * (q.e - p.e) + (q.n - p.n) * (q.n - p.n);
        if (slack > 0.0 && len2 <= slack * slack) return;
      }
    } else if (EdgeBelowItsSectors(p, q)) {
      return;
    }
    // Stationary point of w(t) / r(t) on the edge (closed form, see header).
    const double a = p.w, b = q.w - p.w;
    const double ve = q.e - p.e, vn = q.n - p.n;
    const double c = p.e * p.e + p.n * p.n, dd = p.e * ve + p.n * vn, ee = ve * ve + vn * vn;
    const double den = b * dd - a * ee;
    double t_star = den != 0.0 ? (a * dd - b * c) / den : -1.0;
    if (!(t_star > 0.0 && t_star < 1.0)) t_star = -1.0;
    int last_sector = p.sector;
    const bool walked = internal::WalkCrossings(*setup_, p, q, [&](int, double t, int before, int after) {
      const SweepPoint x = internal::Lerp(p, q, t);
      Update(before, x);
      Update(after, x);
      if (t_star >= 0.0) {
        if (t_star <= t) {
          Update(before, internal::Lerp(p, q, t_star));
          t_star = -1.0;
        }
      }
      last_sector = after;
    });
    if (walked && t_star >= 0.0) Update(last_sector, internal::Lerp(p, q, t_star));
  }

  // The bilinear surface inside a cell, along each boundary ray that cuts
  // it: w is quadratic along the chord and r linear, so the maximum of w / r
  // is at the chord's ends (the edge crossings, counted in Edge) or at a
  // root of C R1 s^2 + 2 C R0 s + (B R0 - A R1) = 0.
  void Quad(const SweepPoint& a, const SweepPoint& b, const SweepPoint& c, const SweepPoint& d) {
    if (a.sector == b.sector && a.sector == c.sector && a.sector == d.sector) return;
    // Skip cells that cannot raise any sector they span: on the cell
    // w <= w_max (the largest corner plus a quarter of the twist) and
    // r >= min corner distance - diagonal.
    const double twist = a.w - b.w - c.w + d.w;
    const double w_max = std::max({a.w, b.w, c.w, d.w}) + 0.25 * std::abs(twist);
    double t = INFINITY;
    const bool walked = internal::CellRays(*setup_, a, b, c, d, [&](int, int before, int after) {
      t = std::min({t, best_[before].tan_el, best_[after].tan_el});
    });
    if (!walked) return;
    const double diag2 = std::max((a.e - d.e) * (a.e - d.e) + (a.n - d.n) * (a.n - d.n),
                                  (b.e - c.e) * (b.e - c.e) + (b.n - c.n) * (b.n - c.n));
    if (w_max < 0.0) {
      if (w_max <= t * (std::max({a.d, b.d, c.d, d.d}) + std::sqrt(diag2))) return;
    } else if (t > 0.0) {
      const double slack = std::min({a.d, b.d, c.d, d.d}) - w_max / t;  // must exceed the diagonal
      if (slack > 0.0 && diag2 <= slack * slack) return;
    }
    internal::CellRays(*setup_, a, b, c, d,
                       [&](int ray, int before, int after) { Chord(a, b, c, d, ray, before, after); });
  }

  void MergeFrom(const HorizonAccumulator& other) {
    for (size_t i = 0; i < best_.size(); ++i)
      if (Better(other.best_[i], best_[i])) best_[i] = other.best_[i];
  }
  struct Best {
    double tan_el = -std::numeric_limits<double>::infinity();
    double d = NAN, e = 0, n = 0, u = 0, h = NAN;
    bool hint = false;  // a hint no terrain has reached yet
  };
  const std::vector<Best>& best() const { return best_; }
  // Whether some bin still holds its hint: no terrain there reached it, so
  // the hint may have culled the terrain that sets the bin.
  bool HintLeft() const {
    return std::any_of(best_.begin(), best_.end(), [](const Best& b) { return b.hint; });
  }

  // The lowest current maximum tan(elevation) over `count` sectors from
  // `first` (wrapping): a tile whose points all stay strictly below it
  // cannot change the result (internal::SweepRows culls it).
  double LowestBest(int first, int count) const {
    double m = std::numeric_limits<double>::infinity();
    const int n = setup_->num_sectors;
    for (int i = 0; i < count; ++i) m = std::min(m, best_[(first + i) % n].tan_el);
    return m;
  }

 private:
  void Update(int s, const SweepPoint& x) {
    const Best c{x.tan_el, x.d, x.e, x.n, x.u, x.h, false};
    if (Better(c, best_[s])) best_[s] = c;
  }
  // Higher, and at equal height nearer: an order that does not depend on
  // which thread saw which point first. Terrain as high as a hint replaces it.
  static bool Better(const Best& a, const Best& b) {
    if (a.tan_el == b.tan_el && b.hint && !a.hint) return true;
    return a.tan_el > b.tan_el || (a.tan_el == b.tan_el && a.tan_el > -std::numeric_limits<double>::infinity() &&
                                   (a.d < b.d || (a.d == b.d && (a.e < b.e || (a.e == b.e && a.n < b.n)))));
  }
  // Whether no point of the edge p -> q can raise any sector it crosses (the
  // sectors WalkCrossings visits, ends included): on the edge w <= max(p.w,
  // q.w) and the distance lies between the segment's nearest point to the
  // observer and its farther end. Near terrain's edges span many sectors,
  // and most lie well under the far ridges that set them. The bound keeps a
  // margin of a micrometre and 1e-9, so what it skips could not have changed
  // a bin, ties included.
  bool EdgeBelowItsSectors(const SweepPoint& p, const SweepPoint& q) const {
    const std::optional<internal::CrossingWalk> walk = internal::WalkOf(*setup_, p, q);
    if (!walk) return false;  // not walked: nothing to skip
    // The count + 1 sectors walked, as a run from its lower end.
    const int n = setup_->num_sectors, count = walk->count;
    const int first = walk->dir > 0 ? p.sector : (p.sector - count + n) % n;
    const double w_max = std::max(p.w, q.w);
    const double w_bound = w_max * (1.0 + std::copysign(1e-9, w_max)) + 1e-6;
    if (w_bound < 0.0) {
      // Lowest where farthest: the farther end.
      const double d_bound = std::max(p.d, q.d) * (1.0 + 1e-9) + 1e-6;
      return w_bound < LowestBest(first, count + 1) * d_bound;
    }
    const double ve = q.e - p.e, vn = q.n - p.n, len2 = ve * ve + vn * vn;
    if (!(len2 > 0.0)) return false;
    const double s = std::clamp(-(p.e * ve + p.n * vn) / len2, 0.0, 1.0);
    const double ne = p.e + s * ve, nn = p.n + s * vn;
    const double r_bound = std::sqrt(ne * ne + nn * nn) * (1.0 - 1e-9) - 1e-6;
    if (!(r_bound > 0.0)) return false;
    const double t = LowestBest(first, count + 1);
    return t > 0.0 && w_bound < t * r_bound;
  }
  bool IsAdjacent(int s1, int s2) const {
    const int diff = std::abs(s1 - s2);
    return diff == 1 || diff == setup_->num_sectors - 1;
  }

  void Chord(const SweepPoint& a, const SweepPoint& b, const SweepPoint& c, const SweepPoint& d, int ray, int before,
             int after) {
    const double ue = setup_->ray_sin[ray], un = setup_->ray_cos[ray];
    // Entry and exit of the ray through the cell's four edges, in cell
    // coordinates (fx east along a-b, fy south along a-c).
    struct Hit {
      double fx, fy, r;
    } hits[2];
    int count = 0;
    auto edge = [&](const SweepPoint& p, const SweepPoint& q, double fx0, double fy0, double dfx, double dfy) {
      const double ve = q.e - p.e, vn = q.n - p.n;
      const double denom = ue * vn - un * ve;
      if (denom == 0.0 || count == 2) return;
      const double t = -(ue * p.n - un * p.e) / denom;
      if (!(t >= 0.0 && t <= 1.0)) return;
      const double r = ue * (p.e + t * ve) + un * (p.n + t * vn);  // along the ray
      if (r <= 0.0) return;
      hits[count++] = {fx0 + t * dfx, fy0 + t * dfy, r};
    };
    edge(a, b, 0, 0, 1, 0);
    edge(c, d, 0, 1, 1, 0);
    edge(a, c, 0, 0, 0, 1);
    edge(b, d, 1, 0, 0, 1);
    if (count < 2) return;
    auto bilinear = [&](double fx, double fy, double va, double vb, double vc, double vd) {
      return (1 - fy) * ((1 - fx) * va + fx * vb) + fy * ((1 - fx) * vc + fx * vd);
    };
    auto w_at = [&](double s) {
      const double fx = hits[0].fx + s * (hits[1].fx - hits[0].fx), fy = hits[0].fy + s * (hits[1].fy - hits[0].fy);
      return bilinear(fx, fy, a.w, b.w, c.w, d.w);
    };
    const double w0 = w_at(0.0), wh = w_at(0.5), w1 = w_at(1.0);
    const double cc = 2.0 * (w1 + w0 - 2.0 * wh), bb = w1 - w0 - cc;
    const double r0 = hits[0].r, r1 = hits[1].r - hits[0].r;
    if (std::abs(cc) < 1e-9) return;  // linear along the chord: maximum at an end
    // C R1 s^2 + 2 C R0 s + (B R0 - A R1) = 0
    const double qa = cc * r1, qb = 2.0 * cc * r0, qc = bb * r0 - w0 * r1;
    double roots[2];
    int nroots = 0;
    if (std::abs(qa) < 1e-12 * std::abs(qb)) {
      roots[nroots++] = -qc / qb;
    } else {
      const double disc = qb * qb - 4.0 * qa * qc;
      if (disc < 0.0) return;
      const double sq = std::sqrt(disc);
      roots[nroots++] = (-qb + sq) / (2.0 * qa);
      roots[nroots++] = (-qb - sq) / (2.0 * qa);
    }
    for (int i = 0; i < nroots; ++i) {
      const double s = roots[i];
      if (!(s > 0.0 && s < 1.0)) continue;
      const double fx = hits[0].fx + s * (hits[1].fx - hits[0].fx), fy = hits[0].fy + s * (hits[1].fy - hits[0].fy);
      SweepPoint x;
      x.w = w0 + bb * s + cc * s * s;
      x.d = r0 + r1 * s;
      x.tan_el = x.w / x.d;
      x.e = ue * x.d;
      x.n = un * x.d;
      x.u = bilinear(fx, fy, a.u, b.u, c.u, d.u);
      x.h = bilinear(fx, fy, a.h, b.h, c.h, d.h);
      Update(before, x);
      Update(after, x);
    }
  }

  const SweepSetup* setup_;
  std::vector<Best> best_;
};

}  // namespace

void HorizonOptions::Check() const {
  if (!(azimuth_step_deg > 0.0) || !(azimuth_step_deg <= 90.0))
    ThrowField("HorizonOptions::azimuth_step_deg", azimuth_step_deg, "0 < step <= 90");
  const double n = 360.0 / azimuth_step_deg;
  if (std::abs(n - std::round(n)) > 1e-6 * n)
    ThrowField("HorizonOptions::azimuth_step_deg", azimuth_step_deg, "360 / step is a whole number");
  if (n > 3'600'000) ThrowField("HorizonOptions::azimuth_step_deg", azimuth_step_deg, "step >= 0.0001");
  if (!(max_distance_m > 0.0) || !std::isfinite(max_distance_m) || max_distance_m > 2'000'000.0)
    ThrowField("HorizonOptions::max_distance_m", max_distance_m, "0 < max_distance_m <= 2000 km");
  if (!(min_distance_m >= 0.0) || !(min_distance_m < max_distance_m))
    ThrowField("HorizonOptions::min_distance_m", min_distance_m, "0 <= min_distance_m < max_distance_m");
  if (!(refraction >= -1.0 && refraction <= 1.0)) ThrowField("HorizonOptions::refraction", refraction, "-1 <= k <= 1");
  if (num_threads < 1 || num_threads > 256) ThrowField("HorizonOptions::num_threads", num_threads, "1..256");
  if (!std::isfinite(sector_center_deg))
    ThrowField("HorizonOptions::sector_center_deg", sector_center_deg, "finite");
  if (!(sector_half_width_deg > 0.0 && sector_half_width_deg <= 180.0))
    ThrowField("HorizonOptions::sector_half_width_deg", sector_half_width_deg, "0 < half width <= 180");
  if (hint_tan_el && static_cast<int>(hint_tan_el->size()) != NumBins())
    ThrowField("HorizonOptions::hint_tan_el", static_cast<double>(hint_tan_el->size()), "NumBins() values");
}

int HorizonOptions::NumBins() const { return static_cast<int>(std::lround(360.0 / azimuth_step_deg)); }

void RidgeOptions::Check() const {
  if (!(min_depth_ratio >= 0.0)) ThrowField("RidgeOptions::min_depth_ratio", min_depth_ratio, ">= 0");
  if (!(min_depth_spacings >= 0.0)) ThrowField("RidgeOptions::min_depth_spacings", min_depth_spacings, ">= 0");
  if (!(min_distance_spacings >= 0.0)) ThrowField("RidgeOptions::min_distance_spacings", min_distance_spacings, ">= 0");
  if (!(min_separation_deg >= 0.0)) ThrowField("RidgeOptions::min_separation_deg", min_separation_deg, ">= 0");
}

double HorizonProfile::ElevationAtDeg(double azimuth_deg) const {
  if (elevation_deg.empty()) return NAN;
  const double x = WrapAzimuthDeg(azimuth_deg) / azimuth_step_deg;
  const int i0 = static_cast<int>(std::floor(x)) % size();
  const int i1 = (i0 + 1) % size();
  const double f = x - std::floor(x);
  return (1 - f) * elevation_deg[i0] + f * elevation_deg[i1];
}

GeodeticPoint ResolveObserver(const TerrainWindow& terrain, double lat_deg, double lon_deg, std::optional<double> agl_m,
                              std::optional<double> alt_m) {
  if (!std::isfinite(lat_deg) || lat_deg < -90.0 || lat_deg > 90.0) ThrowField("latitude", lat_deg, "-90 <= lat <= 90");
  if (!std::isfinite(lon_deg) || lon_deg < -180.0 || lon_deg > 360.0)
    ThrowField("longitude", lon_deg, "-180 <= lon <= 360");
  if (agl_m && alt_m) throw InvalidArgument("give either a height above ground (agl) or an altitude, not both");
  if (agl_m && (!std::isfinite(*agl_m) || *agl_m < -100.0 || *agl_m > 100000.0))
    ThrowField("agl", *agl_m, "-100 <= agl <= 100000 m");
  if (alt_m && (!std::isfinite(*alt_m) || *alt_m < -1000.0 || *alt_m > 100000.0))
    ThrowField("alt", *alt_m, "-1000 <= alt <= 100000 m");
  const std::optional<double> ground = terrain.HeightAt(lat_deg, lon_deg);
  if (!ground) {
    std::ostringstream m;
    m << "observer (" << lat_deg << ", " << lon_deg << ") has no DEM data under it";
    throw InvalidArgument(m.str());
  }
  return {lat_deg, lon_deg, alt_m ? *alt_m : *ground + agl_m.value_or(kDefaultEyeHeightM)};
}

HorizonProfile ComputeHorizon(const TerrainWindow& terrain, const GeodeticPoint& observer,
                              const HorizonOptions& options) {
  options.Check();
  const LocalFrame frame(observer);
  const int n = options.NumBins();
  const SweepSetup setup =
      internal::MakeSweepSetup(n, 0.5, options.min_distance_m, options.max_distance_m, options.refraction);
  auto sweep = [&](bool hinted) {
    auto accs = internal::SweepGrids<HorizonAccumulator>(terrain.grids, frame, setup, options.pool, options.num_threads,
                                                         [&] { return HorizonAccumulator(setup, options, hinted); });
    for (size_t i = 1; i < accs.size(); ++i) accs[0].MergeFrom(accs[i]);
    return accs;
  };
  auto accs = sweep(options.hint_tan_el != nullptr);
  if (accs[0].HintLeft()) accs = sweep(false);  // a hint too high: the terrain it may have culled is needed

  HorizonProfile out;
  out.observer = observer;
  out.ground_height_m = terrain.HeightAt(observer.lat_deg, observer.lon_deg).value_or(NAN);
  out.azimuth_step_deg = 360.0 / n;
  out.refraction = options.refraction;
  out.elevation_deg.assign(n, NAN);
  out.distance_m.assign(n, NAN);
  out.lat_deg.assign(n, NAN);
  out.lon_deg.assign(n, NAN);
  out.height_m.assign(n, NAN);
  out.post_spacing_m.assign(n, NAN);
  out.relief_slope.assign(n, NAN);
  std::vector<double> spacing;
  for (const DemGrid& g : terrain.grids) spacing.push_back(g.width >= 2 && g.height >= 2 ? g.SpacingM() : NAN);
  size_t grid = 0;  // the horizon's neighbouring bins mostly lie in the same grid: try the last one first
  // The grid holding (lat, lon) with data, and the fractional post there.
  struct GridPoint {
    size_t grid;
    double col, row;
  };
  auto grid_at = [&](double lat, double lon) -> std::optional<GridPoint> {
    for (size_t k = 0; k < terrain.grids.size(); ++k) {
      const size_t g = (grid + k) % terrain.grids.size();
      const auto px = terrain.grids[g].PixelOf(lat, lon);
      if (px && terrain.grids[g].HeightAtPixel(px->first, px->second)) {
        grid = g;
        return GridPoint{g, px->first, px->second};
      }
    }
    return std::nullopt;
  };
  // Steepest descent from the point to the points one post away in the 8
  // directions of the grid (along rows, columns and diagonals), rise over run.
  auto relief_at = [&](const GridPoint& p, double s) {
    const DemGrid& g = terrain.grids[p.grid];
    const std::optional<double> h0 = g.HeightAtPixel(p.col, p.row);
    if (!h0 || !(s > 0.0)) return static_cast<double>(NAN);
    double steepest = 0.0;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const std::optional<double> h = g.HeightAtPixel(p.col + dx, p.row + dy);
        if ((dx || dy) && h) steepest = std::max(steepest, (*h0 - *h) / (s * std::hypot(dx, dy)));
      }
    return steepest;
  };
  const auto& best = accs[0].best();
  for (int i = 0; i < n; ++i) {
    const auto& b = best[i];
    if (!std::isfinite(b.tan_el)) continue;
    out.elevation_deg[i] = RadToDeg(std::atan(b.tan_el));
    out.distance_m[i] = b.d;
    const GeodeticPoint g = frame.GeodeticFromEnu({b.e, b.n, b.u});
    out.lat_deg[i] = g.lat_deg;
    out.lon_deg[i] = g.lon_deg;
    out.height_m[i] = b.h;
    const std::optional<GridPoint> gp = grid_at(g.lat_deg, g.lon_deg);
    out.post_spacing_m[i] = gp ? spacing[gp->grid] : *std::max_element(spacing.begin(), spacing.end());
    if (gp) out.relief_slope[i] = relief_at(*gp, spacing[gp->grid]);
  }
  return out;
}

std::vector<Eigen::Vector3d> HorizonPoints(const HorizonProfile& horizon) {
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < horizon.size(); ++i)
    if (std::isfinite(horizon.elevation_deg[i]) && std::isfinite(horizon.height_m[i]))
      out.push_back(EcefFromGeodetic({horizon.lat_deg[i], horizon.lon_deg[i], horizon.height_m[i]}));
  return out;
}

std::vector<double> HorizonHints(const std::vector<Eigen::Vector3d>& points_ecef, const GeodeticPoint& observer,
                                 const HorizonOptions& options) {
  // Below the point's own elevation by 1e-5 (0.0006 deg): rounding, and a
  // point inside an edge that lies within one bin from here (the sweep
  // counts that edge's ends only), do not leave a hint above the bin.
  constexpr double kMargin = 1e-5;
  const int n = options.NumBins();
  std::vector<double> hint(n, NAN);
  const LocalFrame frame(observer);
  const double lift = options.refraction / (2.0 * kRefractionEarthRadiusM);
  const double bins_per_rad = n / (2.0 * kPi);
  for (const Eigen::Vector3d& ecef : points_ecef) {
    const Eigen::Vector3d p = frame.EnuFromEcef(ecef);
    const double d = std::hypot(p.x(), p.y());
    if (!(d >= options.min_distance_m && d <= options.max_distance_m)) continue;
    double az = std::atan2(p.x(), p.y());
    if (az < 0.0) az += 2.0 * kPi;
    const int bin = static_cast<int>(std::floor(az * bins_per_rad + 0.5)) % n;
    const double t = (p.z() + lift * d * d) / d - kMargin;
    if (!(hint[bin] >= t)) hint[bin] = t;
  }
  return hint;
}

HorizonProfile ComputeHorizonNear(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                  const HorizonOptions& options, const std::vector<Eigen::Vector3d>& nearby_points) {
  const std::vector<double> hints = HorizonHints(nearby_points, observer, options);
  HorizonOptions hinted = options;
  hinted.hint_tan_el = &hints;
  return ComputeHorizon(terrain, observer, hinted);
}

HorizonProfile ComputeHorizonNear(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                  const HorizonOptions& options, const HorizonProfile& nearby) {
  return ComputeHorizonNear(terrain, observer, options, HorizonPoints(nearby));
}

}  // namespace horizonreg
