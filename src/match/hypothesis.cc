// SPDX-License-Identifier: MIT
#include "match/hypothesis.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "util/angles.h"

namespace horizonreg {

std::optional<PaperHypothesis> PaperHypothesisFromPairs(const ImagePoint& p1, const ImagePoint& p2,
                                                        const HorizonPoint& h1, const HorizonPoint& h2, double cx,
                                                        double cy) {
  const double x1 = p1.x - cx, x2 = p2.x - cx;
  // Image y grows downwards; the paper's y grows upwards with elevation.
  const double y1 = cy - p1.y, y2 = cy - p2.y;
  const double dx = x2 - x1, dy = y2 - y1;
  const double dalpha = AngDiffDeg(h2.azimuth_deg, h1.azimuth_deg);
  if (!(dx > 0.0) || !(dalpha > 0.0) || std::abs(x2) < 1e-9) return std::nullopt;
  const double da = DegToRad(dalpha);
  PaperHypothesis h;
  // Eq. (5): alpha_c = alpha_2 - arctan(sin(da) / (cos(da) - x1 / x2)), the
  // arctangent taken on the branch where x2 and tan(alpha_2 - alpha_c) agree in sign.
  double beta2 = std::atan2(std::sin(da), std::cos(da) - x1 / x2);
  if (beta2 > kPi / 2) beta2 -= kPi;
  if (beta2 < -kPi / 2) beta2 += kPi;
  h.azimuth_deg = WrapAzimuthDeg(h2.azimuth_deg - RadToDeg(beta2));
  // Eq. (8): C_x = dx / (2 cos((alpha_1 + alpha_2 - 2 alpha_c) / 2) sin(da / 2)), pixels per radian.
  const double mean_offset =
      DegToRad(0.5 * (AngDiffDeg(h1.azimuth_deg, h.azimuth_deg) + AngDiffDeg(h2.azimuth_deg, h.azimuth_deg)));
  h.cx_px_per_deg = DegToRad(dx / (2.0 * std::cos(mean_offset) * std::sin(da / 2.0)));
  // Eq. (9): C_y = dy / d(theta); eq. (6): theta_c = (theta_1 y2 - theta_2 y1) / dy.
  const double dtheta = h2.elevation_deg - h1.elevation_deg;
  if (std::abs(dy) > 1e-9) {
    h.cy_px_per_deg = dy / dtheta;
    h.pitch_deg = (h1.elevation_deg * y2 - h2.elevation_deg * y1) / dy;
  } else {  // same image height: C_y is undetermined, take square pixels
    h.cy_px_per_deg = h.cx_px_per_deg;
    h.pitch_deg = h1.elevation_deg - y1 / h.cy_px_per_deg;
  }
  if (!std::isfinite(h.pitch_deg) || !std::isfinite(h.cy_px_per_deg)) return std::nullopt;
  return h;
}

namespace {

Eigen::Vector3d EnuOf(const HorizonPoint& h) {
  const double az = DegToRad(h.azimuth_deg), el = DegToRad(h.elevation_deg);
  return {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
}

// Cosine of the angle between the rays through two pixels (offsets from the
// principal point) for focal length f.
double RayCosine(const Eigen::Vector2d& u1, const Eigen::Vector2d& u2, double f) {
  const double f2 = f * f;
  return (u1.dot(u2) + f2) / std::sqrt((u1.squaredNorm() + f2) * (u2.squaredNorm() + f2));
}

// Rotation R with R a_i ~ b_i for two pairs of unit vectors (triad on the
// bisectors, which splits any mismatch of the two angles evenly).
Eigen::Matrix3d TwoVectorRotation(const Eigen::Vector3d& a1, const Eigen::Vector3d& a2, const Eigen::Vector3d& b1,
                                  const Eigen::Vector3d& b2) {
  auto frame = [](const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
    const Eigen::Vector3d s = (v1 + v2).normalized(), d = (v1 - v2).normalized();
    Eigen::Matrix3d m;
    m.col(0) = s;
    m.col(1) = d;
    m.col(2) = s.cross(d);
    return m;
  };
  return frame(b1, b2) * frame(a1, a2).transpose();
}

}  // namespace

std::vector<PoseHypothesis> TwoPointPoses(const ImagePoint& p1, const ImagePoint& p2, const HorizonPoint& h1,
                                          const HorizonPoint& h2, double cx, double cy, double min_focal_px,
                                          double max_focal_px) {
  std::vector<PoseHypothesis> out;
  const Eigen::Vector3d d1 = EnuOf(h1), d2 = EnuOf(h2);
  const double target = d1.dot(d2);
  const Eigen::Vector2d u1(p1.x - cx, p1.y - cy), u2(p2.x - cx, p2.y - cy);
  if ((u1 - u2).norm() < 1e-9 || target > 1.0 - 1e-12 || !(min_focal_px > 0 && max_focal_px > min_focal_px)) return out;
  // cos(angle) = (a + F) / sqrt((b + F)(c + F)) with F = f^2: squared, a
  // quadratic in F; keep the roots where a + F has the sign of the cosine.
  const double pa = u1.dot(u2), pb = u1.squaredNorm(), pc = u2.squaredNorm(), t2 = target * target;
  const double qa = 1.0 - t2, qb = 2.0 * pa - t2 * (pb + pc), qc = pa * pa - t2 * pb * pc;
  double roots[2];
  int n = 0;
  if (std::abs(qa) < 1e-15) {
    if (std::abs(qb) > 0) roots[n++] = -qc / qb;
  } else {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0) {
      const double sq = std::sqrt(disc);
      const double q = -0.5 * (qb + (qb >= 0 ? sq : -sq));  // stable roots
      roots[n++] = q / qa;
      if (q != 0) roots[n++] = qc / q;
    }
  }
  std::sort(roots, roots + n);
  for (int i = 0; i < n; ++i) {
    const double big_f = roots[i];
    if (!(big_f > 0)) continue;
    const double f = std::sqrt(big_f);
    if (f < min_focal_px || f > max_focal_px) continue;
    if (std::abs(RayCosine(u1, u2, f) - target) > 1e-9) continue;  // a root of the squared equation only
    if (i == 1 && n == 2 && std::abs(roots[1] - roots[0]) < 1e-12 * roots[1]) continue;
    const Eigen::Vector3d r1 = Eigen::Vector3d(u1.x() / f, u1.y() / f, 1.0).normalized();
    const Eigen::Vector3d r2 = Eigen::Vector3d(u2.x() / f, u2.y() / f, 1.0).normalized();
    out.push_back({PoseFromCamFromEnu(TwoVectorRotation(d1, d2, r1, r2)), f});  // maps d_i onto r_i
  }
  return out;
}

}  // namespace horizonreg
