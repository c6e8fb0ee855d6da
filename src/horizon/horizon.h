// SPDX-License-Identifier: MIT
// The 360-degree terrain horizon seen from an observer (paper, sections 2.2
// and 4.2), and the inner ridge lines (the paper's surface silhouettes S_s).
#pragma once

#include <cmath>
#include <optional>
#include <vector>

#include "dem/terrain.h"
#include "geo/geodesy.h"
#include "util/thread_pool.h"

namespace horizonreg {

struct HorizonOptions {
  double azimuth_step_deg = 0.25;          // Bin width and spacing; 360 / step must be a whole number.
  double max_distance_m = 100'000.0;       // Terrain farther than this (ground distance) is ignored.
  double min_distance_m = 0.5;             // Posts nearer than this (the observer's own post) are ignored.
  double refraction = kDefaultRefraction;  // k of the lift k d^2 / (2 R); 0 = pure geometry, in [-1, 1].
  int num_threads = 2;                     // Threads for the post/edge pass, >= 1 (when no pool is given).
  ThreadPool* pool = nullptr;              // A shared pool to run on instead (then num_threads is unused).
  // Only the bins whose centres lie within sector_half_width_deg of
  // sector_center_deg are computed (the others are NaN; terrain seen only
  // there is culled): a view's horizon at a fraction of the cost.
  // ComputeHorizon only; 180 = the whole circle.
  double sector_center_deg = 0.0;
  double sector_half_width_deg = 180.0;
  // Whether a bin centred at azimuth_deg lies within the sector.
  bool InSector(double azimuth_deg) const {
    return !(std::abs(std::remainder(azimuth_deg - sector_center_deg, 360.0)) > sector_half_width_deg);
  }
  // Lower bounds of the result, tan(elevation) per bin (NumBins() values,
  // NaN where none; HorizonHints): terrain that cannot rise above them is
  // culled sooner. The result is the same as without them: should some
  // bin's terrain not reach its hint, the horizon is computed again without
  // hints. ComputeHorizon only.
  const std::vector<double>* hint_tan_el = nullptr;
  void Check() const;                      // Throws InvalidArgument naming the field.
  int NumBins() const;
};

// Per azimuth bin i (centre i * step, clockwise from north) the highest
// elevation angle of terrain inside the azimuth segment
// [(i - 0.5) step, (i + 0.5) step) and where that terrain is. NaN where the
// segment holds no terrain (beyond the DEM or max_distance).
struct HorizonProfile {
  GeodeticPoint observer;        // eye position; height_m above the ellipsoid (conventions.h)
  double ground_height_m = 0.0;  // terrain height under the observer
  double azimuth_step_deg = 0.25;
  double refraction = kDefaultRefraction;
  std::vector<double> elevation_deg;               // elevation angle, degrees, up positive (may be negative)
  std::vector<double> distance_m;                  // horizontal distance in the observer's ENU frame (= ground
                                                   // distance within 0.1%)
  std::vector<double> lat_deg, lon_deg, height_m;  // the horizon point, height as in the DEM
  std::vector<double> post_spacing_m;              // post spacing of the DEM grid the horizon point lies in
  // Steepest descent from the horizon point over one post spacing (rise
  // over run, >= 0): how sharp the terrain is there (a ridge's flanks, a
  // dome's shoulder), which sets how much the grid cuts off it.
  std::vector<double> relief_slope;

  int size() const { return static_cast<int>(elevation_deg.size()); }
  double AzimuthDeg(int i) const { return i * azimuth_step_deg; }
  // Elevation angle at any azimuth, linearly interpolated between bin centres.
  double ElevationAtDeg(double azimuth_deg) const;
};

// Eye position for an observer at (lat, lon): terrain height + agl_m, or
// alt_m (absolute) when given. Throws InvalidArgument when lat/lon are out of
// range or not finite, or no DEM grid has data there.
GeodeticPoint ResolveObserver(const TerrainWindow& terrain, double lat_deg, double lon_deg, std::optional<double> agl_m,
                              std::optional<double> alt_m);

// Computes the horizon of the bilinear terrain surface (dem/dem_grid.h).
//
// Algorithm: every post within max_distance is placed in the observer's ENU
// frame exactly (closed-form ECEF, rows and columns share their
// trigonometry), lifted by refraction, and counted in the bin of its azimuth.
// Every grid edge (the straight line between two neighbouring posts, along
// which the bilinear surface is linear) that crosses a bin boundary is cut at
// the boundary rays, and each piece contributes the maximum of its elevation
// angle, found in closed form (endpoints, or the interior stationary point of
// w(t) / r(t)). So a near cell that spans several segments counts in all of
// them, and no segment is left empty near the observer. The maxima inside a
// cell's interior (not on a grid line) are not searched; they differ from the
// grid-line maxima by far less than 0.01 deg except within a few cells.
// Accuracy against a fine ray march of the same surface: median < 0.002 deg
// (horizon/horizon_test.cc).
// Thread-safe: terrain is only read. Throws InvalidArgument if options.Check()
// fails.
HorizonProfile ComputeHorizon(const TerrainWindow& terrain, const GeodeticPoint& observer,
                              const HorizonOptions& options);

// Each bin's horizon point (where it has one), ECEF: what HorizonHints reads.
std::vector<Eigen::Vector3d> HorizonPoints(const HorizonProfile& horizon);

// Hints (HorizonOptions::hint_tan_el) for the horizon at `observer` from a
// horizon computed nearby on the same terrain (HorizonPoints): each point,
// a point of the terrain, seen from `observer` (a little lower), in the bin
// of `options` it falls in; bins no point falls in get none (measured: a
// horizon 1-4 km away hints about 80% of a real photo's view, one 360 m
// away 77% of a synthetic circle of ridges).
std::vector<double> HorizonHints(const std::vector<Eigen::Vector3d>& points_ecef, const GeodeticPoint& observer,
                                 const HorizonOptions& options);

// ComputeHorizon hinted by a horizon computed nearby on the same terrain
// (HorizonHints of its HorizonPoints): the same result, sooner.
HorizonProfile ComputeHorizonNear(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                  const HorizonOptions& options, const std::vector<Eigen::Vector3d>& nearby_points);
HorizonProfile ComputeHorizonNear(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                  const HorizonOptions& options, const HorizonProfile& nearby);

// One inner ridge line crossing of an azimuth: terrain that forms a
// silhouette against terrain farther behind it.
struct Ridge {
  double elevation_deg = 0.0;
  double distance_m = 0.0;
};

struct RidgeOptions {
  double min_depth_ratio = 0.10;       // Terrain behind a ridge must be hidden over >= this fraction of its distance.
  double min_depth_spacings = 3.0;     // ... and over >= this many DEM post spacings.
  double min_distance_spacings = 4.0;  // Ridges nearer than this many post spacings are ignored.
  double min_separation_deg = 0.02;    // A ridge must stand this far below the next silhouette above it.
  void Check() const;
};

// For each bin centre azimuth, the silhouettes nearer than the outer horizon,
// ordered from the highest (farthest) to the lowest (nearest). The profile
// along each azimuth is the bilinear surface sampled where the ray crosses
// grid lines. A silhouette at distance d is a point whose elevation angle is
// above all nearer terrain and behind which the terrain stays hidden (below
// it) over a depth >= max(min_depth_ratio d, min_depth_spacings * spacing).
// The outer horizon itself is not repeated. Thread-safe.
std::vector<std::vector<Ridge>> ComputeRidges(const TerrainWindow& terrain, const GeodeticPoint& observer,
                                              const HorizonOptions& options, const RidgeOptions& ridge_options);

}  // namespace horizonreg
