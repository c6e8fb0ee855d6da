// SPDX-License-Identifier: MIT
#include "dem/dem_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "geo/geodesy.h"
#include "util/angles.h"

namespace horizonreg {

std::optional<std::pair<double, double>> DemGrid::PixelOf(double query_lat_deg, double query_lon_deg) const {
  if (width < 2 || height < 2) return std::nullopt;
  double col, row;
  if (separable) {
    row = (query_lat_deg - lat0_deg) / dlat_deg;
    col = AngDiffDeg(query_lon_deg, lon0_deg) / dlon_deg;
    if (col < -1e-9 && dlon_deg > 0) col = (AngDiffDeg(query_lon_deg, lon0_deg) + 360.0) / dlon_deg;
  } else {
    // Start from the affine guess, then Newton on the bilinear position map.
    const double dlon = AngDiffDeg(query_lon_deg, lon_deg[0]);
    col = col_from_lonlat[0] + col_from_lonlat[1] * dlon + col_from_lonlat[2] * (query_lat_deg - lat_deg[0]);
    row = row_from_lonlat[0] + row_from_lonlat[1] * dlon + row_from_lonlat[2] * (query_lat_deg - lat_deg[0]);
    for (int it = 0; it < 8; ++it) {
      const int c = std::clamp(static_cast<int>(std::floor(col)), 0, width - 2);
      const int r = std::clamp(static_cast<int>(std::floor(row)), 0, height - 2);
      const double fx = col - c, fy = row - r;
      auto lat = [&](int cc, int rr) { return LatAt(cc, rr); };
      auto lon = [&](int cc, int rr) { return LonAt(cc, rr); };
      const double la = (1 - fy) * ((1 - fx) * lat(c, r) + fx * lat(c + 1, r)) +
                        fy * ((1 - fx) * lat(c, r + 1) + fx * lat(c + 1, r + 1));
      const double lo = (1 - fy) * ((1 - fx) * lon(c, r) + fx * lon(c + 1, r)) +
                        fy * ((1 - fx) * lon(c, r + 1) + fx * lon(c + 1, r + 1));
      const double dla_dx = (1 - fy) * (lat(c + 1, r) - lat(c, r)) + fy * (lat(c + 1, r + 1) - lat(c, r + 1));
      const double dla_dy = (1 - fx) * (lat(c, r + 1) - lat(c, r)) + fx * (lat(c + 1, r + 1) - lat(c + 1, r));
      const double dlo_dx = (1 - fy) * (lon(c + 1, r) - lon(c, r)) + fy * (lon(c + 1, r + 1) - lon(c, r + 1));
      const double dlo_dy = (1 - fx) * (lon(c, r + 1) - lon(c, r)) + fx * (lon(c + 1, r + 1) - lon(c + 1, r));
      const double det = dla_dx * dlo_dy - dla_dy * dlo_dx;
      if (det == 0.0) break;
      const double ela = query_lat_deg - la, elo = AngDiffDeg(query_lon_deg, lo);
      const double dc = (dlo_dy * ela - dla_dy * elo) / det, dr = (-dlo_dx * ela + dla_dx * elo) / det;
      // Converged to the last bit: the iterations left would repeat this one.
      if (col + dc == col && row + dr == row) break;
      col += dc;
      row += dr;
    }
  }
  const double eps = 1e-9;
  if (!(col >= -eps && row >= -eps && col <= width - 1 + eps && row <= height - 1 + eps)) return std::nullopt;
  return std::make_pair(std::clamp(col, 0.0, width - 1.0), std::clamp(row, 0.0, height - 1.0));
}

std::optional<double> DemGrid::HeightAt(double query_lat_deg, double query_lon_deg) const {
  const auto px = PixelOf(query_lat_deg, query_lon_deg);
  return px ? HeightAtPixel(px->first, px->second) : std::nullopt;
}

std::optional<double> DemGrid::HeightAtPixel(double col, double row) const {
  if (width < 2 || height < 2 || !(col >= 0.0 && row >= 0.0 && col <= width - 1.0 && row <= height - 1.0))
    return std::nullopt;
  const int c = std::min(static_cast<int>(col), width - 2);
  const int r = std::min(static_cast<int>(row), height - 2);
  const double fx = col - c, fy = row - r;
  const double h =
      (1 - fy) * ((1 - fx) * At(c, r) + fx * At(c + 1, r)) + fy * ((1 - fx) * At(c, r + 1) + fx * At(c + 1, r + 1));
  if (!std::isfinite(h)) return std::nullopt;
  return h;
}

void DemGrid::IndexTrig() {
  post_trig.clear();
  const size_t n = static_cast<size_t>(width) * height;
  if (separable || lat_deg.size() != n || lon_deg.size() != n) return;
  post_trig.resize(4 * n);
  for (size_t k = 0; k < n; ++k) {
    const double lat = DegToRad(lat_deg[k]), lon = DegToRad(lon_deg[k]);
    post_trig[4 * k] = std::sin(lat), post_trig[4 * k + 1] = std::cos(lat);
    post_trig[4 * k + 2] = std::sin(lon), post_trig[4 * k + 3] = std::cos(lon);
  }
}

void DemGrid::IndexPositions() {
  post_trig.clear();
  if (separable || width < 2 || height < 2) return;
  // (lon, lat) offsets of the posts (w-1, 0) and (0, h-1) from post (0, 0).
  const double a = AngDiffDeg(LonAt(width - 1, 0), LonAt(0, 0)), b = LatAt(width - 1, 0) - LatAt(0, 0);
  const double c = AngDiffDeg(LonAt(0, height - 1), LonAt(0, 0)), d = LatAt(0, height - 1) - LatAt(0, 0);
  const double det = a * d - b * c;
  if (det == 0.0) return;
  // [col; row] = [[w-1, 0], [0, h-1]] * inverse([[a, c], [b, d]]) * [dlon; dlat]
  col_from_lonlat[1] = (width - 1) * d / det;
  col_from_lonlat[2] = -(width - 1) * c / det;
  row_from_lonlat[1] = -(height - 1) * b / det;
  row_from_lonlat[2] = (height - 1) * a / det;
}

double DemGrid::SpacingM() const {
  const int c = width / 2, r = height / 2;
  const int c1 = std::min(c + 1, width - 1), r1 = std::min(r + 1, height - 1);
  LocalFrame frame({LatAt(c, r), LonAt(c, r), 0.0});
  const double dx = frame.EnuFromGeodetic({LatAt(c1, r), LonAt(c1, r), 0.0}).norm();
  const double dy = frame.EnuFromGeodetic({LatAt(c, r1), LonAt(c, r1), 0.0}).norm();
  return std::max(dx, dy);
}

void DemGrid::IndexBlocks() {
  for (int l = 0; l < 3; ++l) {
    const int size = kBlock >> l;
    const int rows = (height + size - 1) / size, cols = width >= 2 ? (width - 1 + size - 1) / size : 0;
    std::vector<float>& out = block_max[l];
    out.assign(static_cast<size_t>(std::max(0, rows)) * std::max(0, cols), -std::numeric_limits<float>::infinity());
    for (int r = 0; r < height; ++r) {
      const float* row = height_m.data() + static_cast<size_t>(r) * width;
      // Row r belongs to block row r / size, and as the row above to the next one.
      const int rb0 = r / size, rb1 = (r + 1) % size == 0 && r + 1 < height ? rb0 + 1 : rb0;
      for (int cb = 0; cb < cols; ++cb) {
        const int c0 = cb * size, c1 = std::min(width - 1, c0 + size);
        float m = -std::numeric_limits<float>::infinity();
        for (int c = c0; c <= c1; ++c) m = row[c] > m ? row[c] : m;  // NaN (void) posts are skipped
        for (int rb = rb0; rb <= rb1; ++rb) {
          float& dst = out[static_cast<size_t>(rb) * cols + cb];
          dst = std::max(dst, m);
        }
      }
    }
  }
}

}  // namespace horizonreg
