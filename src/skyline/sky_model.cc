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
  struct Sample {
    double t[kTerms];
    double v[3];
  };
  std::vector<Sample> samples;
  const double sx = 1.0 / std::max(1, w - 1), sy = 1.0 / std::max(1, h - 1);
  for (int c = 0; c < w; c += stride) {
    const float* l = lab.l.ptr<float>(c);
    const float* a = lab.a.ptr<float>(c);
    const float* b = lab.b.ptr<float>(c);
    const float* d = dev ? dev->ptr<float>(c) : nullptr;
    for (int r = 0; r < std::min(top[c], h); r += stride) {
      if (d && !(d[r] < max_dev)) continue;
      Sample s;
      Terms(c * sx - 0.5, r * sy, s.t);
      s.v[0] = l[r], s.v[1] = a[r], s.v[2] = b[r];
      samples.push_back(s);
    }
  }
  if (samples.size() < 64) return false;
  std::vector<double> weight(samples.size(), 1.0), residual(samples.size(), 0.0);
  double scale = scale_floor;
  // Graduated: the first rounds weigh residuals against a wide scale (the
  // sky's own smooth variation stays in; snow and clouds, tens of delta E
  // off, mostly leave), then against 2.5 robust sigmas.
  constexpr double kWide[] = {12.0, 6.0};
  for (int iter = 0; iter < 7; ++iter) {
    Eigen::Matrix<double, kTerms, kTerms> ata = Eigen::Matrix<double, kTerms, kTerms>::Zero();
    Eigen::Matrix<double, kTerms, 3> atb = Eigen::Matrix<double, kTerms, 3>::Zero();
    for (size_t i = 0; i < samples.size(); ++i) {
      const Eigen::Map<const Eigen::Matrix<double, kTerms, 1>> t(samples[i].t);
      ata.noalias() += weight[i] * t * t.transpose();
      for (int ch = 0; ch < 3; ++ch) atb.col(ch) += weight[i] * samples[i].v[ch] * t;
    }
    ata.diagonal().array() += 1e-6 * ata.diagonal().maxCoeff();  // a thin band cannot pin the cubic terms
    const Eigen::Matrix<double, kTerms, 3> x = ata.ldlt().solve(atb);
    for (int ch = 0; ch < 3; ++ch)
      for (int k = 0; k < kTerms; ++k) coef_[ch][k] = x(k, ch);
    for (size_t i = 0; i < samples.size(); ++i) {
      double d2 = 0.0;
      for (int ch = 0; ch < 3; ++ch) {
        double p = 0.0;
        for (int k = 0; k < kTerms; ++k) p += coef_[ch][k] * samples[i].t[k];
        d2 += (samples[i].v[ch] - p) * (samples[i].v[ch] - p);
      }
      residual[i] = std::sqrt(d2);
    }
    scale = std::max<double>(scale_floor, 1.4826 * MedianOf(residual));
    const double width = iter < 2 ? kWide[iter] : 2.5 * scale;
    for (size_t i = 0; i < samples.size(); ++i) {
      const double z = residual[i] / width;
      weight[i] = 1.0 / (1.0 + z * z);
    }
  }
  scale_ = static_cast<float>(scale);
  fitted_ = true;
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
    // Per column the model is a cubic in y: c0 + c1 y + c2 y^2 + c3 y^3.
    float poly[3][4];
    for (int ch = 0; ch < 3; ++ch) {
      const auto& k = coef_[ch];
      poly[ch][0] = static_cast<float>(k[0] + k[1] * x + k[3] * x * x);
      poly[ch][1] = static_cast<float>(k[2] + k[4] * x + k[7] * x * x);
      poly[ch][2] = static_cast<float>(k[5] + k[8] * x);
      poly[ch][3] = static_cast<float>(k[6]);
    }
    for (int r = 0; r < h; ++r) {
      const float y = static_cast<float>(r * sy);
      pl[r] = poly[0][0] + y * (poly[0][1] + y * (poly[0][2] + y * poly[0][3]));
      pa[r] = poly[1][0] + y * (poly[1][1] + y * (poly[1][2] + y * poly[1][3]));
      pb[r] = poly[2][0] + y * (poly[2][1] + y * (poly[2][2] + y * poly[2][3]));
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

}  // namespace horizonreg::skyline_detail
