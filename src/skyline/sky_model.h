// SPDX-License-Identifier: MIT
// Internal to the skyline module: the sky's colour as a smooth function of
// the position in the image, fitted robustly to the pixels above a first
// boundary, and how far every pixel departs from it. A colour histogram
// mixes the deep blue at the top with the pale sky near the horizon, where
// white snow falls too; the expected sky colour *at that place* tells them
// apart (real photos: sky within ~2 delta E of the model, snow, haze-blue
// ridges and rock 5-60 delta E off).
#pragma once

#include <array>
#include <vector>

#include "skyline/lab.h"

namespace horizonreg::skyline_detail {

class SkyModel {
 public:
  // Fits L, a and b each to a polynomial in the normalised position (x
  // across, y down, both in [0, 1]): 1, x, y, x^2, xy, y^2, y^3, x^2 y,
  // x y^2, by iteratively reweighted least squares (Cauchy weights at 2.5
  // times the robust residual scale) over the pixels of the transposed work
  // planes (one row per image column) above top[c] in column c; every
  // `stride`-th column and row is used. The scale is at least scale_floor
  // (delta E; rendered skies have no noise). Returns false when fewer than
  // 64 pixels are available (then the model is flat: no information).
  bool Fit(const LabPlanes& lab, const std::vector<int>& top, int stride, float scale_floor);
  // The same over the pixels above top[c] whose deviation from this model
  // (Deviation(), `dev`) is below max_dev: grows the sky region past what
  // the first fit saw (the blue between clouds) without taking in what
  // departs from it (snow). Keeps the current model when too few pixels.
  bool Refit(const LabPlanes& lab, const std::vector<int>& top, const cv::Mat& dev, float max_dev, int stride,
             float scale_floor);
  // Per pixel of the planes: the colour distance to the model, in units of
  // its robust scale (planes layout: one row per column), into `dev`. Below
  // the rows a column was fitted to, the model is continued as a straight
  // line in y from the last of them (a cubic's own extrapolation climbs to
  // the colour of the snow under a grey sky that lightens downwards). And,
  // when `darker` is given, how much darker than the model the pixel is
  // (predicted L* minus L*), in the same units.
  void Deviation(const LabPlanes& lab, cv::Mat& dev, cv::Mat* darker = nullptr) const;
  // The model's colour (L*, a*, b*) at a place of the planes it was fitted
  // on (column c across, row r down, fractional), continued below the
  // fitted rows as Deviation() continues it. Flat zero when not fitted.
  void Predict(double c, double r, float out[3]) const;
  float scale() const { return scale_; }
  bool fitted() const { return fitted_; }

 private:
  static constexpr int kTerms = 9;
  using Cubic = std::array<std::array<float, 4>, 3>;  // per channel: c0 + c1 y + c2 y^2 + c3 y^3
  // The model along the column at normalised x (-0.5 .. 0.5): a cubic in y.
  Cubic ColumnCubic(double x) const;
  // A channel's cubic at y, continued as a straight line (its value and
  // slope at y_end) below y_end.
  static float Continued(const std::array<float, 4>& p, float y, float y_end);
  bool FitMasked(const LabPlanes& lab, const std::vector<int>& top, const cv::Mat* dev, float max_dev, int stride,
                 float scale_floor);
  std::array<std::array<double, kTerms>, 3> coef_{};  // per channel
  std::vector<int> top_;  // per column: the rows above it were fitted
  int w_ = 0, h_ = 0;     // the planes' columns and rows
  float scale_ = 1.0f;
  bool fitted_ = false;
};

}  // namespace horizonreg::skyline_detail
