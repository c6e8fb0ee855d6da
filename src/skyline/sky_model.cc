// SPDX-License-Identifier: MIT
#include "skyline/sky_model.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace horizonreg::skyline_detail {
namespace {

inline void Terms(double x, double y, double* t) {
  t[0] = 1.0;
  t[1] = x;
  t[2] = y;
  t[3] = x * x;
  t[4] = x * y;
  t[5] = y * y;
  t[6] = y * y * y;
  t[7] = x * x * y;
  t[8] = x * y * y;
}

double MedianOf(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

bool SkyModel::Fit(const LabPlanes& lab, const std::vector<int>& top, int stride, float scale_floor) {
  fitted_ = false;
  for (auto& c : coef_) c.fill(0.0);
  scale_ = std::max(scale_floor, 1.0f);
  return FitMasked(lab, top, nullptr, 0.0f, stride, scale_floor);
}

bool SkyModel::Refit(const LabPlanes& lab, const std::vector<int>& top, const cv::Mat& dev, float max_dev, int stride,
                     float scale_floor) {
  return FitMasked(lab, top, &dev, max_dev, stride, scale_floor);
}

bool SkyModel::FitMasked(const LabPlanes& lab, const std::vector<int>& top, const cv::Mat* dev, float max_dev,
                         int stride, float scale_floor) {
  const int w = lab.Rows(), h = lab.Cols();
  const double sx = 1.0 / std::max(1, w - 1), sy = 1.0 / std::max(1, h - 1);
  // The samples: design rows (the polynomial's terms) and colours.
  std::vector<std::array<double, kTerms + 3>> rows_in;
  for (int c = 0; c < w; c += stride) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    const float* d = dev ? dev->ptr<float>(c) : nullptr;
    for (int r = 0; r < std::min(top[c], h); r += stride) {
      if (d && !(d[r] < max_dev)) continue;
      std::array<double, kTerms + 3> row;
      Terms(c * sx - 0.5, r * sy, row.data());
      row[kTerms] = l[r], row[kTerms + 1] = a[r], row[kTerms + 2] = b[r];
      rows_in.push_back(row);
    }
  }
  const Eigen::Index n = static_cast<Eigen::Index>(rows_in.size());
  if (n < 64) return false;
  Eigen::Matrix<double, Eigen::Dynamic, kTerms> design(n, kTerms);
  Eigen::Matrix<double, Eigen::Dynamic, 3> colour(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (int k = 0; k < kTerms; ++k) design(i, k) = rows_in[i][k];
    for (int ch = 0; ch < 3; ++ch) colour(i, ch) = rows_in[i][kTerms + ch];
  }
  Eigen::VectorXd weight = Eigen::VectorXd::Ones(n);
  Eigen::Matrix<double, kTerms, 3> x;
  double scale = scale_floor;
  // Graduated: the first rounds weigh residuals against a wide scale (the
  // sky's own smooth variation stays in; snow and clouds, tens of delta E
  // off, mostly leave), then against 2.5 robust sigmas.
  constexpr double kWide[] = {12.0, 6.0};
  std::vector<double> residual(n);
  for (int iter = 0; iter < 6; ++iter) {
    const Eigen::Matrix<double, Eigen::Dynamic, kTerms> weighted = weight.asDiagonal() * design;
    Eigen::Matrix<double, kTerms, kTerms> ata = design.transpose() * weighted;
    const Eigen::Matrix<double, kTerms, 3> atb = weighted.transpose() * colour;
    ata.diagonal().array() += 1e-6 * ata.diagonal().maxCoeff();  // a thin band cannot pin the cubic terms
    x = ata.ldlt().solve(atb);
    const Eigen::Matrix<double, Eigen::Dynamic, 3> r = colour - design * x;
    for (Eigen::Index i = 0; i < n; ++i) residual[i] = r.row(i).norm();
    std::vector<double> sorted = residual;
    scale = std::max<double>(scale_floor, 1.4826 * MedianOf(std::move(sorted)));
    const double width = iter < 2 ? kWide[iter] : 2.5 * scale;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double z = residual[i] / width;
      weight[i] = 1.0 / (1.0 + z * z);
    }
  }
  for (int ch = 0; ch < 3; ++ch)
    for (int k = 0; k < kTerms; ++k) coef_[ch][k] = x(k, ch);
  scale_ = static_cast<float>(scale);
  fitted_ = true;
  top_ = top;
  w_ = w, h_ = h;
  return true;
}

void SkyModel::Deviation(const LabPlanes& lab, cv::Mat& dev, cv::Mat* darker) const {
  const int w = lab.Rows(), h = lab.Cols();
  dev.create(w, h, CV_32F);
  if (darker) darker->create(w, h, CV_32F);
  if (!fitted_) {
    dev.setTo(0.0f);
    if (darker) darker->setTo(0.0f);
    return;
  }
  const double sx = 1.0 / std::max(1, w - 1), sy = 1.0 / std::max(1, h - 1);
  const float inv = 1.0f / scale_;
  std::vector<float> pl(h), pa(h), pb(h);
  for (int c = 0; c < w; ++c) {
    const double x = c * sx - 0.5;
    const Cubic poly = ColumnCubic(x);
    // Below the rows it was fitted to in this column, the cubic is
    // continued as a straight line (its value and slope at the last row):
    // a cubic's own extrapolation can climb to the colour of the snow below.
    const int fitted_rows = c < static_cast<int>(top_.size()) ? std::min(top_[c], h) : h;
    const float y_end = static_cast<float>(std::max(0, fitted_rows - 1) * sy);
    for (int r = 0; r < h; ++r) {
      const float y = static_cast<float>(r * sy);
      pl[r] = Continued(poly[0], y, y_end);
      pa[r] = Continued(poly[1], y, y_end);
      pb[r] = Continued(poly[2], y, y_end);
    }
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    float* out = dev.ptr<float>(c);
    for (int r = 0; r < h; ++r) {
      const float dl = l[r] - pl[r], da = a[r] - pa[r], db = b[r] - pb[r];
      out[r] = std::sqrt(dl * dl + da * da + db * db) * inv;
    }
    if (darker) {
      float* dk = darker->ptr<float>(c);
      for (int r = 0; r < h; ++r) dk[r] = (pl[r] - l[r]) * inv;
    }
  }
}

SkyModel::Cubic SkyModel::ColumnCubic(double x) const {
  Cubic poly;
  for (int ch = 0; ch < 3; ++ch) {
    const auto& k = coef_[ch];
    poly[ch][0] = static_cast<float>(k[0] + k[1] * x + k[3] * x * x);
    poly[ch][1] = static_cast<float>(k[2] + k[4] * x + k[7] * x * x);
    poly[ch][2] = static_cast<float>(k[5] + k[8] * x);
    poly[ch][3] = static_cast<float>(k[6]);
  }
  return poly;
}

float SkyModel::Continued(const std::array<float, 4>& p, float y_at, float y_end) {
  const float y = std::min(y_at, y_end);
  float v = p[0] + y * (p[1] + y * (p[2] + y * p[3]));
  if (const float dy = y_at - y; dy > 0) v += dy * (p[1] + y * (2 * p[2] + 3 * y * p[3]));
  return v;
}

void SkyModel::Predict(double c, double r, float out[3]) const {
  out[0] = out[1] = out[2] = 0.0f;
  if (!fitted_) return;
  const double sx = 1.0 / std::max(1, w_ - 1), sy = 1.0 / std::max(1, h_ - 1);
  const int col = std::clamp(static_cast<int>(std::lround(c)), 0, std::max(0, w_ - 1));
  const int fitted_rows = col < static_cast<int>(top_.size()) ? std::min(top_[col], h_) : h_;
  const Cubic poly = ColumnCubic(c * sx - 0.5);
  const float y_end = static_cast<float>(std::max(0, fitted_rows - 1) * sy);
  for (int ch = 0; ch < 3; ++ch) out[ch] = Continued(poly[ch], static_cast<float>(r * sy), y_end);
}

}  // namespace horizonreg::skyline_detail
