// SPDX-License-Identifier: MIT
// Internal to the match module: scoring a pose against the skyline columns,
// the paper's linear corrections (eq. 11-14), the robust least squares and
// the statistics the no-match decision reads. Not a public header.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "match/fit_model.h"

namespace horizonreg::match_detail {

// The skyline in the fitting's coordinates: offsets from the principal
// point, lens distortion removed when the lens is known (then in pixels of
// focal length fx), as observed otherwise (principal point at the centre).
class ImageFrame {
 public:
  ImageFrame(const Skyline& skyline, const std::optional<CameraIntrinsics>& known) {
    if (known) {
      lens_ = known->width == skyline.width && known->height == skyline.height
                  ? *known
                  : known->Resized(skyline.width, skyline.height);
    }
    width_ = skyline.width;
    height_ = skyline.height;
  }
  bool known() const { return lens_.has_value(); }
  // Offset (u, v) of a pixel; nullopt outside the lens model.
  std::optional<Eigen::Vector2d> Offset(double x, double y) const {
    if (!lens_) return Eigen::Vector2d(x - width_ / 2.0, y - height_ / 2.0);
    const auto xy = lens_->NormalizedFromPixel({x, y});
    if (!xy) return std::nullopt;
    return Eigen::Vector2d(lens_->focal_px * xy->x(), lens_->focal_px * xy->y());
  }
  // The camera for a fitted pose (focal f and k1 when the lens is not known).
  CameraIntrinsics Intrinsics(const Pose4& p) const {
    if (lens_) return *lens_;
    CameraIntrinsics k = CameraIntrinsics::FromHfov(width_, height_, 60.0);
    k.focal_px = p.f;
    if (p.k1 != 0.0) k.distortion = LensDistortion::Radial(p.k1);
    return k;
  }
  double KnownFocalPx() const { return lens_ ? lens_->focal_px : NAN; }

 private:
  std::optional<CameraIntrinsics> lens_;
  int width_ = 0, height_ = 0;
};

// The visible skyline columns in the fitting's coordinates (left to right).
std::vector<Column> VisibleColumns(const Skyline& skyline, const ImageFrame& frame);
// `count` columns spread evenly over `all` (all of them when fewer).
std::vector<Column> Subsample(const std::vector<Column>& all, int count);
// The skyline's pixel noise (1 sigma) for an image `width` pixels wide.
inline double SigmaPx(const RegistrationOptions& o, int width) { return o.inlier_px * ToleranceScale(width) / 3.0; }
// The DEM error model with its flattening scaled (the flattening an image shows).
inline DemErrorModel ScaledModel(DemErrorModel m, double scale) {
  m.flattening_spacings *= scale;
  m.flattening_floor_deg *= scale;
  return m;
}

// The chi^2 (ColumnLoss) above which a column is an outlier: 3 sigma.
inline constexpr double kGateChi2 = 9.0;

// The box k1 is fitted in (RefineLeastSquares): +-kK1Bound, four times its
// prior's default sigma; no lens a skyline is fitted to comes near it.
inline constexpr double kK1Bound = 0.6;

class Scorer {
 public:
  // sigma_px: the skyline's pixel noise (1 sigma); image_height_px sets the
  // outlier density of the robust fit.
  Scorer(const HorizonLookup& horizon, const DemErrorModel& model, double sigma_px, double image_height_px,
         double outlier_share);
  // Exact residual (ColumnResidual) of column c at pose p.
  double Residual(const Eigen::Matrix3d& cam_from_enu, const Pose4& p, const Column& c) const;
  // Mean truncated cost over the columns: chi^2 plus the cost of the
  // column's tolerance width (ColumnLoss::WidthCost), at most kGateChi2
  // (vertical distances, the DEM error model looked up at each column's
  // azimuth, fast arctangent); stops early and returns infinity once above
  // `bound`. For ranking hypotheses.
  double Cost(const Pose4& p, const std::vector<Column>& cols, double bound = INFINITY) const {
    return Sum(p, cols, bound, true);
  }
  // Mean truncated chi^2 alone (no width cost): how badly the pose misses
  // the skyline, for the ambiguity ratio.
  double Misfit(const Pose4& p, const std::vector<Column>& cols) const;
  // Share of the columns whose residuals under poses a and b agree within
  // tol_px: near 1 when both predict the same image skyline (one solution).
  double Agreement(const Pose4& a, const Pose4& b, const std::vector<Column>& cols, double tol_px) const;
  // Share of the columns inside the gate (unweighted).
  double InlierShare(const Pose4& p, const std::vector<Column>& cols) const;
  // Sets each column's slope weight, noise and flattening for the pose.
  void Reweight(const Pose4& p, std::vector<Column>& cols) const;
  // Posterior probability that a column with this residual is not misread
  // (mixture of ColumnLoss and a uniform outlier density over the image).
  double InlierProbability(const Column& c, double r, double noise_scale = 1.0) const;

  const HorizonLookup& horizon() const { return horizon_; }
  double sigma_px() const { return sigma_px_; }

 private:
  double Sum(const Pose4& p, const std::vector<Column>& cols, double bound, bool width) const;
  const HorizonLookup& horizon_;
  DemErrorModel model_;
  double sigma_px_, log_outlier_density_, log_inlier_prior_;
};

struct Refined {
  Pose4 pose;
  double sigma[5] = {NAN, NAN, NAN, NAN, NAN};  // yaw, pitch, roll (rad), f (px), k1
};

struct LeastSquaresOptions {
  int rounds = 3;                     // IRLS rounds at the final noise scale
  std::vector<double> anneal = {};    // noise scale factors before those rounds (e.g. 8, 4, 2)
  bool fix_focal = false;
  // The focal length kept within 0.2-5 times the start's. Ceres then
  // line-searches every step of the fit (bounds make it project each step),
  // which took half of the fits' time; without the bound, Levenberg-
  // Marquardt's own damping alone (RegistrationOptions::bound_search_focal).
  bool bound_focal = true;
  bool fit_k1 = false;
  double k1_prior_sigma = 0.15;
  bool want_covariance = false;
  double effective_fraction = 1.0;  // share of the columns that are independent (for the sigmas)
};

// Robust nonlinear least squares of yaw, pitch, roll, focal length and
// (optionally) k1: Levenberg-Marquardt (Ceres) inside iteratively reweighted
// least squares with the one-sided loss and the outlier mixture. Columns
// must have been Reweight()ed for a nearby pose.
Refined RefineLeastSquares(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start,
                           const LeastSquaresOptions& options);

// Paper eq. (11)-(14): closest-point differences between the columns and
// the projected DEM silhouette, straight-line fits of their horizontal and
// vertical components, corrections of azimuth, pitch, roll and focal length.
struct PaperCorrection {
  Pose4 pose;
  double ex_px = NAN, ey_px = NAN;
  int matched = 0;  // columns with a closest point within 3 tau (the last iteration's)
};
PaperCorrection CorrectLinear(const Scorer& scorer, const std::vector<Column>& cols, const Pose4& start, int width,
                              double tau_px);

// Statistics at a pose over all columns (Reweight()ed for it).
struct FitStats {
  double inlier_fraction = 0.0;  // inliers weighted by their information over that plus the outliers (each 1)
  double informative_columns = 0.0;  // sum of the columns' information weights (at most 1 each)
  // Independent samples behind the inliers: the columns on one DEM
  // resolution cell (the larger of the bin step and post spacing /
  // distance) share its error and count as one as far as that error
  // dominates their variance (a coarse DEM, near terrain, a zoomed-in view),
  // each counting when the pixel noise does; times the information weight.
  double independent_inliers = 0.0;
  // The outliers by side: the skyline below the DEM horizon (terrain read
  // as sky: haze, snow, cloud in front of a ridge) or above it (sky read as
  // terrain, or something nearer than the DEM shows).
  int outliers_below = 0, outliers_above = 0;
  // Of outliers_above, those in runs that rise out of the fitted skyline
  // (hidden by something nearer), and the inlier share without them.
  int hidden_columns = 0;
  double unhidden_inlier_fraction = 0.0;
  double rms_px = NAN;           // raw residuals of the inliers
  // The inliers' chi^2 against what the model expects of them, as a pixel
  // RMS: sigma sqrt(sum chi^2 / sum E[chi^2]) (sigma for a pose whose
  // residuals follow the noise and DEM error model).
  double model_rms_px = NAN;
  DemLimits dem;
};
FitStats ComputeFitStats(const Scorer& scorer, const Pose4& p, const std::vector<Column>& cols, int width = 0);

}  // namespace horizonreg::match_detail
