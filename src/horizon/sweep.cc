// SPDX-License-Identifier: MIT
#include "horizon/sweep.h"

#include "util/vector_clones.h"

namespace horizonreg::internal {

namespace {

// Branch-free FastAtan2 (same series), for vectorisation.
inline double Atan2NoBranch(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double mx = std::max(ax, ay), mn = std::min(ax, ay);
  const double a0 = mn / (mx + 1e-300);
  const bool big = a0 > 0.41421356237309503;
  const double reduced = (a0 - 1.0) / (a0 + 1.0);  // computed always: no branch
  const double a = big ? reduced : a0;
  const double z2 = a * a;
  double r =
      a * (1.0 + z2 * (-1.0 / 3 + z2 * (1.0 / 5 + z2 * (-1.0 / 7 + z2 * (1.0 / 9 + z2 * (-1.0 / 11 + z2 / 13))))));
  r += big ? 0.78539816339744831 : 0.0;
  r = ay > ax ? 1.5707963267948966 - r : r;
  r = x < 0.0 ? 3.141592653589793 - r : r;
  return y < 0.0 ? -r : r;
}

template <bool kSeparable, bool kUnitStride>
inline void ComputeRowImpl(const RowInput& in, RowScratch& out) {
  const double sp0 = in.obs_sin_lat, cp0 = in.obs_cos_lat, x0 = in.obs_x, z0 = in.obs_z;
  const double one_minus_e2 = 1.0 - kWgs84E2;
  double* __restrict oe = out.e.data();
  double* __restrict on = out.n.data();
  double* __restrict ou = out.u.data();
  double* __restrict ow = out.w.data();
  double* __restrict od = out.d.data();
  double* __restrict ot = out.tan_el.data();
  int* __restrict os = out.sector.data();
  const int n = in.count, stride = kUnitStride ? 1 : in.stride, sectors = in.num_sectors;
  const double two_pi = 2.0 * kPi;
  double* __restrict heights = out.h.data();
  for (int c = 0; c < n; ++c) heights[c] = in.heights[c];
#pragma omp simd
  for (int c = 0; c < n; c += stride) {
    const double h = heights[c];
    double sp, cp, nr;
    if constexpr (kSeparable) {
      sp = in.row_sin_lat, cp = in.row_cos_lat, nr = in.row_n;
    } else {
      sp = in.post_sin_lat[c], cp = in.post_cos_lat[c];
      nr = kWgs84A / std::sqrt(1.0 - kWgs84E2 * sp * sp);
    }
    const double hh = h == h ? h : 0.0;  // NaN (void) posts are flagged below
    const double a = (nr + hh) * cp;
    const double dx = a * in.col_cos_dlon[c] - x0;
    const double dz = (nr * one_minus_e2 + hh) * sp - z0;
    const double e = a * in.col_sin_dlon[c];
    const double nn = -sp0 * dx + cp0 * dz;
    const double u = cp0 * dx + sp0 * dz;
    const double d2 = e * e + nn * nn;
    const double d = std::sqrt(d2);
    const double w = u + in.lift_scale * d2;
    double az = Atan2NoBranch(e, nn);
    az = az < 0.0 ? az + two_pi : az;
    int s = static_cast<int>(az * in.inv_step + in.sector_offset);  // az >= 0: truncation is floor
    s = s >= sectors ? s - sectors : s;
    const bool valid = (h == h) & (d2 >= in.min_d2) & (d2 <= in.max_d2);  // & not &&: no branch
    oe[c] = e, on[c] = nn, ou[c] = u, ow[c] = w, od[c] = d;
    ot[c] = w / (d + 1e-300);  // invalid posts may hold garbage; sector says so
    os[c] = valid ? s : -1;
  }
}

}  // namespace

HR_VECTOR_CLONES void ComputeRow(const RowInput& in, RowScratch& out) {
  const bool unit = in.stride == 1;
  if (in.post_sin_lat == nullptr) {
    unit ? ComputeRowImpl<true, true>(in, out) : ComputeRowImpl<true, false>(in, out);
  } else {
    unit ? ComputeRowImpl<false, true>(in, out) : ComputeRowImpl<false, false>(in, out);
  }
}

}  // namespace horizonreg::internal
