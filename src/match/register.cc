// SPDX-License-Identifier: MIT
#include "match/register.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <tuple>

#include "geo/geodesy.h"
#include "match/extrema.h"
#include "match/fit.h"
#include "match/hypothesis.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

using match_detail::Column;
using match_detail::HorizonLookup;
using match_detail::ImageFrame;
using match_detail::LeastSquaresOptions;
using match_detail::PaperCorrection;
using match_detail::Pose4;
using match_detail::Refined;
using match_detail::Scorer;
using match_detail::ScaledModel;
using match_detail::SigmaPx;
using match_detail::Subsample;
using match_detail::VisibleColumns;

void SensorPrior::Check() const {
  if (compass_deg && !std::isfinite(*compass_deg)) ThrowField("SensorPrior::compass_deg", *compass_deg, "finite");
  if (pitch_deg && !(std::abs(*pitch_deg) <= 90.0))
    ThrowField("SensorPrior::pitch_deg", *pitch_deg, "-90 <= pitch <= 90");
  if (roll_deg && !(std::abs(*roll_deg) <= 180.0)) ThrowField("SensorPrior::roll_deg", *roll_deg, "-180 <= roll <= 180");
  if (!(compass_sigma_deg > 0.0 && compass_sigma_deg < 180.0))
    ThrowField("SensorPrior::compass_sigma_deg", compass_sigma_deg, "0 < sigma < 180");
  if (!(inclinometer_sigma_deg > 0.0 && inclinometer_sigma_deg < 90.0))
    ThrowField("SensorPrior::inclinometer_sigma_deg", inclinometer_sigma_deg, "0 < sigma < 90");
  if (!(gate_sigmas > 0.0 && std::isfinite(gate_sigmas)))
    ThrowField("SensorPrior::gate_sigmas", gate_sigmas, "0 < gate_sigmas < inf");
}

void DemErrorModel::Check() const {
  if (!(flattening_spacings >= 0.0 && flattening_spacings <= 10.0))
    ThrowField("DemErrorModel::flattening_spacings", flattening_spacings, "0 <= value <= 10");
  if (!(flattening_floor_deg >= 0.0 && flattening_floor_deg <= 5.0))
    ThrowField("DemErrorModel::flattening_floor_deg", flattening_floor_deg, "0 <= value <= 5");
  if (!(typical_slope > 0.0 && std::isfinite(typical_slope)))
    ThrowField("DemErrorModel::typical_slope", typical_slope, "0 < value < inf");
  if (!(position_sigma_m >= 0.0 && position_sigma_m <= 100'000.0))
    ThrowField("DemErrorModel::position_sigma_m", position_sigma_m, "0 <= value <= 100 km");
  if (!(height_sigma_m >= 0.0 && height_sigma_m <= 100'000.0))
    ThrowField("DemErrorModel::height_sigma_m", height_sigma_m, "0 <= value <= 100 km");
}

void RegistrationOptions::Check() const {
  if (!(min_hfov_deg > 0.0 && min_hfov_deg < 170.0))
    ThrowField("RegistrationOptions::min_hfov_deg", min_hfov_deg, "0 < min_hfov_deg < 170");
  if (!(max_hfov_deg >= min_hfov_deg && max_hfov_deg < 170.0))
    ThrowField("RegistrationOptions::max_hfov_deg", max_hfov_deg, "min_hfov_deg <= max_hfov_deg < 170");
  if (known_intrinsics) known_intrinsics->Check();
  if (!(distortion_min_span >= 0.0 && distortion_min_span <= 1.0))
    ThrowField("RegistrationOptions::distortion_min_span", distortion_min_span, "0 <= span <= 1");
  if (!(principal_point_range >= 0.0 && principal_point_range <= 0.5))
    ThrowField("RegistrationOptions::principal_point_range", principal_point_range, "0 <= range <= 0.5");
  if (!(distortion_prior_sigma > 0.0))
    ThrowField("RegistrationOptions::distortion_prior_sigma", distortion_prior_sigma, "> 0");
  if (!(max_abs_roll_deg >= 0.0 && max_abs_roll_deg <= 180.0))
    ThrowField("RegistrationOptions::max_abs_roll_deg", max_abs_roll_deg, "0 <= max_abs_roll_deg <= 180");
  if (image_extrema < 2) ThrowField("RegistrationOptions::image_extrema", image_extrema, "image_extrema >= 2");
  if (horizon_extrema < 2) ThrowField("RegistrationOptions::horizon_extrema", horizon_extrema, "horizon_extrema >= 2");
  if (!(min_image_prominence_px >= 0.0))
    ThrowField("RegistrationOptions::min_image_prominence_px", min_image_prominence_px, ">= 0");
  if (!(min_horizon_prominence_deg >= 0.0))
    ThrowField("RegistrationOptions::min_horizon_prominence_deg", min_horizon_prominence_deg, ">= 0");
  if (coarse_columns < 8) ThrowField("RegistrationOptions::coarse_columns", coarse_columns, "coarse_columns >= 8");
  if (refine_columns < 8) ThrowField("RegistrationOptions::refine_columns", refine_columns, "refine_columns >= 8");
  if (candidates < 2) ThrowField("RegistrationOptions::candidates", candidates, "candidates >= 2");
  if (quick_columns < 8) ThrowField("RegistrationOptions::quick_columns", quick_columns, "quick_columns >= 8");
  if (refined_candidates < 2)
    ThrowField("RegistrationOptions::refined_candidates", refined_candidates, "refined_candidates >= 2");
  if (num_threads < 1) ThrowField("RegistrationOptions::num_threads", num_threads, "num_threads >= 1");
  if (!(inlier_px > 0.0)) ThrowField("RegistrationOptions::inlier_px", inlier_px, "inlier_px > 0");
  if (!(outlier_share > 0.0 && outlier_share < 1.0))
    ThrowField("RegistrationOptions::outlier_share", outlier_share, "0 < share < 1");
  dem_error.Check();
  if (!(min_visible_fraction >= 0.0 && min_visible_fraction <= 1.0))
    ThrowField("RegistrationOptions::min_visible_fraction", min_visible_fraction, "0 <= f <= 1");
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0))
    ThrowField("RegistrationOptions::min_inlier_fraction", min_inlier_fraction, "0 <= f <= 1");
  if (!(min_unhidden_inlier_fraction >= 0.0 && min_unhidden_inlier_fraction <= 1.0))
    ThrowField("RegistrationOptions::min_unhidden_inlier_fraction", min_unhidden_inlier_fraction, "0 <= f <= 1");
  if (!(max_rms_px > 0.0)) ThrowField("RegistrationOptions::max_rms_px", max_rms_px, "max_rms_px > 0");
  if (!(min_misfit_ratio >= 0.0 && min_misfit_ratio <= 1.0))
    ThrowField("RegistrationOptions::min_misfit_ratio", min_misfit_ratio, "0 <= min_misfit_ratio <= 1");
  if (!(min_ambiguity_ratio >= 1.0))
    ThrowField("RegistrationOptions::min_ambiguity_ratio", min_ambiguity_ratio, "min_ambiguity_ratio >= 1");
  if (!(min_informative_fraction >= 0.0 && min_informative_fraction <= 1.0))
    ThrowField("RegistrationOptions::min_informative_fraction", min_informative_fraction, "0 <= f <= 1");
  if (!(min_evidence_nats >= 0.0)) ThrowField("RegistrationOptions::min_evidence_nats", min_evidence_nats, ">= 0");
  prior.Check();
}

double ToleranceScale(int width) { return std::max(1.0, width / 1000.0); }

CameraIntrinsics Registration::Intrinsics(int width, int height) const {
  if (intrinsics.width == width && intrinsics.height == height) return intrinsics;
  if (intrinsics.width > 0) return intrinsics.Resized(width, height);
  CameraIntrinsics k = CameraIntrinsics::FromHfov(width, height, 60.0);
  k.focal_px = focal_px;
  return k;
}

namespace {

// A fitted k1 at the end of its box (match_detail::kK1Bound): the fit bent
// the lens as far as it may to lay the skyline on the DEM horizon, which no
// lens does (the real photos and all their copies registered at their
// stations fit k1 between -0.34 and +0.11). The DEM horizon is then the
// wrong one: half-width crops of AKJNC_20120813 given places 2 and 5 km
// away registered 2.8 and 13.9 deg off with k1 at +0.6 (eval_real.py
// --modes ring-crop-narrow, 2026-12-03).
bool K1AtBound(double k1) { return std::abs(k1) >= (1.0 - 1e-3) * match_detail::kK1Bound; }
constexpr const char* kK1AtBoundMessage =
    "the skyline fits only with the lens bent to the end of its range (a wrong position or DEM?; k1 ";

double PriorPenalty(const SensorPrior& prior, const CameraPose& pose) {
  double chi2 = 0.0;
  if (prior.compass_deg)
    chi2 += std::pow(AngDiffDeg(pose.azimuth_deg, *prior.compass_deg) / prior.compass_sigma_deg, 2);
  if (prior.pitch_deg) chi2 += std::pow((pose.pitch_deg - *prior.pitch_deg) / prior.inclinometer_sigma_deg, 2);
  if (prior.roll_deg) chi2 += std::pow((pose.roll_deg - *prior.roll_deg) / prior.inclinometer_sigma_deg, 2);
  return chi2;
}

}  // namespace

bool RegistrationOptions::WithinRuledOutDeg(const CameraPose& a, const CameraPose& b) {
  return std::abs(AngDiffDeg(a.azimuth_deg, b.azimuth_deg)) < kRuledOutDeg &&
         std::abs(a.pitch_deg - b.pitch_deg) < kRuledOutDeg;
}

bool RegistrationOptions::RulesOut(const CameraPose& pose) const {
  return std::any_of(ruled_out_rivals.begin(), ruled_out_rivals.end(),
                     [&](const CameraPose& q) { return WithinRuledOutDeg(pose, q); });
}

bool WithinPrior(const RegistrationOptions& o, const CameraPose& pose) {
  const SensorPrior& pr = o.prior;
  const double g = pr.gate_sigmas;
  if (pr.compass_deg && std::abs(AngDiffDeg(pose.azimuth_deg, *pr.compass_deg)) > g * pr.compass_sigma_deg)
    return false;
  if (pr.pitch_deg && std::abs(pose.pitch_deg - *pr.pitch_deg) > g * pr.inclinometer_sigma_deg + 1.0) return false;
  if (pr.roll_deg) return std::abs(pose.roll_deg - *pr.roll_deg) <= g * pr.inclinometer_sigma_deg + 1.0;
  return std::abs(pose.roll_deg) <= o.max_abs_roll_deg;
}

namespace {

// The columns hidden by something in front, when there are any, and how
// much of the rest fits against the share that would have passed.
std::string HiddenShare(int hidden, double unhidden_fraction, const RegistrationOptions& o) {
  if (hidden <= 0) return "";
  std::ostringstream m;
  m << " (" << std::lround(100 * unhidden_fraction) << "% of it with the " << hidden
    << " columns hidden by something in front left out, " << std::lround(100 * o.min_unhidden_inlier_fraction)
    << "% needed)";
  return m.str();
}

// Which side of the DEM horizon most of the best pose's misses lie on, for
// the no-match message: what the user can look for in the photo (a wrong
// pose's misses fall either side).
std::string MissesSide(int below, int above) {
  std::ostringstream m;
  if (below >= 3 * std::max(1, above))
    m << "; most misses (" << below << " columns) lie below it: terrain read as sky (haze, snow, cloud)?";
  else if (above >= 3 * std::max(1, below))
    m << "; most misses (" << above << " columns) lie above it: cloud read as terrain, or something nearer than "
      << "the DEM shows (trees, buildings)?";
  return m.str();
}

struct Candidate {
  Pose4 pose;
  double cost = INFINITY;
  double inliers = 0.0;  // share of the columns inside the gate
  double misfit = INFINITY;  // Scorer::Misfit
};

// Cheaper first; equal costs by the pose, so that the order never depends
// on the order in which threads found the candidates.
bool ByCost(const Candidate& x, const Candidate& y) {
  if (x.cost != y.cost) return x.cost < y.cost;
  return std::tie(x.pose.yaw, x.pose.pitch, x.pose.roll, x.pose.f) <
         std::tie(y.pose.yaw, y.pose.pitch, y.pose.roll, y.pose.f);
}
// Hypotheses kept after scoring (the refinement draws its distinct
// candidates from these).
constexpr size_t kKeptHypotheses = 64;
// A narrow window of opening angles (RegistrationOptions::NarrowHfovWindow)
// refines each candidate from more starts, its focal length this factor
// longer and shorter (Register, multi_start).
constexpr double kFocalStartFactor = 1.03;
// Longest gap in the skyline bridged for finding its peaks and dips, as a
// share of the width.
constexpr double kMaxBridgedGap = 0.03;

// Fewer hypotheses from the pairs of peaks and dips than this, and the
// azimuth is also scanned (ScanAzimuths).
constexpr int kScanBelowHypotheses = 16;
constexpr double kScanStepDeg = 0.2;  // azimuth step of the scan
constexpr size_t kScanKept = 32;      // the scan's best local minima scored (and up to as many more distinct poses)
constexpr double kScanFocalStep = 1.02;  // focal lengths scanned over the window, this ratio apart ...
constexpr int kScanMaxFocals = 16;        // ... at most this many (a wider window is not scanned) ...
constexpr int kScanMaxFocalsCompass = 160;  // ... or this many where a compass bounds the azimuths

bool SamePose(const Pose4& a, const Pose4& b, double width);

// Hypotheses of a skyline too plain for pairs of peaks and dips: a gentle
// ridge, or most of the skyline hidden behind near trees (a rendered view
// with its terrain skyline 40% visible: two image extrema, no pair of them
// matching a DEM pair at the opening angle known). Each azimuth (every
// kScanStepDeg) at each focal length of a narrow window: the pitch and
// roll that best lay the columns on the DEM horizon there (linearised
// about a level camera, least squares trimmed twice), ranked by a
// truncated square of the residuals; the best kScanKept local minima in
// azimuth, then up to kScanKept more that are each a pose distinct from
// every one kept (SamePose), are scored as the pairs' hypotheses are. Only
// the azimuths a compass prior admits; empty when the window of opening
// angles is wide and no compass bounds the azimuths.
// The distinct ones are the rivals: a plain skyline's best minima can all
// be one solution (one azimuth at the window's 11 focal lengths, and the
// minima a rough ridge leaves beside it), and the search then refined 3
// distinct poses, none of them a rival, and called the pose unambiguous:
// the centre half of CG05_20050811_190000 (one image extremum, 190
// informative columns) given a position 2 km away registered so 95.6 deg
// off (`eval_real.py --modes ring-crop-narrow`); with them (those among
// the best 64 hypotheses of all, Register) a rival fits within 12% and it
// answers no_match. AK01b_20090827 given a place 5 km
// off without the altitude and its opening angle (`--modes
// ring-noalt-hfov`) registered 165.4 deg off at an ambiguity of 1.40, the
// gate; with them 1.14. Measured and not kept: the distinct ones only
// (no repeats of the best minimum) lost the true pose of a plain skyline
// over a rough ridge, its nearest start dropped as the same pose as a
// better-scoring one (unit test TheAzimuthScanKeepsDistinctPoses); the
// distinct ones refined only when the search found no alternative among
// the rest kept the 165.4 deg registration.
std::vector<Candidate> ScanAzimuths(const Scorer& scorer, const HorizonLookup& lookup, const std::vector<Column>& cols,
                                    const RegistrationOptions& options, double fmin, double fmax, double tau_px,
                                    double width) {
  const SensorPrior& prior = options.prior;
  const double compass_span = prior.compass_deg ? prior.gate_sigmas * prior.compass_sigma_deg : 180.0;
  const bool bounded = compass_span < 180.0;
  std::vector<double> focals;
  if (fmax <= fmin * (1.0 + 1e-9)) {
    focals.push_back(fmin);
  } else {
    const int n = static_cast<int>(std::ceil(std::log(fmax / fmin) / std::log(kScanFocalStep))) + 1;
    if (n > (bounded ? kScanMaxFocalsCompass : kScanMaxFocals)) return {};
    for (int k = 0; k < n; ++k) focals.push_back(fmin * std::pow(fmax / fmin, k / (n - 1.0)));  // n >= 2 here
  }
  if (cols.size() < 8) return {};
  const double first_deg = bounded ? *prior.compass_deg - compass_span : 0.0;
  const bool closed = !bounded;  // the whole circle: the first and last azimuths are neighbours
  const int steps =
      static_cast<int>(std::lround((bounded ? 2.0 * compass_span : 360.0) / kScanStepDeg)) + (bounded ? 1 : 0);
  const double max_roll = DegToRad(options.max_abs_roll_deg);
  struct Hit {
    double score, yaw, pitch, roll, f;
  };
  std::vector<Hit> hits;
  const size_t n = cols.size();
  std::vector<double> az0(n), el0(n), da(n), db(n), r(n), sorted(n);
  // Each column's ray from a level camera looking north, and how its
  // elevation moves with pitch and roll (numerically: the signs follow
  // CamFromEnuRad's conventions whatever they are).
  constexpr double kDelta = 1e-3;
  const Eigen::Matrix3d level = CamFromEnuRad(0.0, 0.0, 0.0).transpose();
  const Eigen::Matrix3d pitched = CamFromEnuRad(0.0, kDelta, 0.0).transpose();
  const Eigen::Matrix3d rolled = CamFromEnuRad(0.0, 0.0, kDelta).transpose();
  auto elevation = [](const Eigen::Vector3d& d) { return std::atan2(d.z(), std::hypot(d.x(), d.y())); };
  for (const double f : focals) {
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d v(cols[i].u / f, cols[i].v / f, 1.0);
      const Eigen::Vector3d d = level * v;
      az0[i] = std::atan2(d.x(), d.y());
      el0[i] = elevation(d);
      da[i] = (elevation(pitched * v) - el0[i]) / kDelta;
      db[i] = (elevation(rolled * v) - el0[i]) / kDelta;
    }
    const double gate = 3.0 * tau_px / f;  // radians
    std::vector<Hit> row(steps);
    for (int s = 0; s < steps; ++s) {
      const double yaw = DegToRad(WrapAzimuthDeg(first_deg + s * kScanStepDeg));
      for (size_t i = 0; i < n; ++i) {
        r[i] = lookup(yaw + az0[i]) - el0[i];
        if (!std::isfinite(r[i])) r[i] = 1.0;  // no horizon there (1 rad): outside every band
      }
      // A level camera's pitch (the median offset), then pitch and roll by
      // least squares over the columns within a wide and a narrow band.
      std::copy(r.begin(), r.end(), sorted.begin());
      std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
      double pitch = sorted[n / 2], roll = 0.0;
      for (const double band : {3.0 * gate, gate}) {
        double saa = 0, sab = 0, sbb = 0, sar = 0, sbr = 0;
        for (size_t i = 0; i < n; ++i) {
          if (std::abs(r[i] - da[i] * pitch - db[i] * roll) > band) continue;
          saa += da[i] * da[i], sab += da[i] * db[i], sbb += db[i] * db[i], sar += da[i] * r[i], sbr += db[i] * r[i];
        }
        const double det = saa * sbb - sab * sab;
        if (!(std::abs(det) > 1e-12)) break;
        pitch = (sar * sbb - sbr * sab) / det;
        roll = (saa * sbr - sab * sar) / det;
      }
      double score = 0.0;
      for (size_t i = 0; i < n; ++i) {
        const double e = (r[i] - da[i] * pitch - db[i] * roll) / gate;
        score += std::min(e * e, 1.0);
      }
      row[s] = {std::abs(roll) <= max_roll ? score : INFINITY, yaw, pitch, roll, f};
    }
    for (int s = 0; s < steps; ++s) {
      const double here = row[s].score;
      const double before = s > 0 || closed ? row[(s + steps - 1) % steps].score : INFINITY;
      const double after = s + 1 < steps || closed ? row[(s + 1) % steps].score : INFINITY;
      if (std::isfinite(here) && here <= before && here < after) hits.push_back(row[s]);
    }
  }
  std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) { return a.score < b.score; });
  std::vector<Candidate> out;
  // The best kScanKept minima, then up to kScanKept more that are each a
  // pose distinct from every one kept (SamePose).
  for (const Hit& h : hits) {
    if (out.size() >= 2 * kScanKept) break;
    const Pose4 pose{h.yaw, h.pitch, h.roll, h.f, 0.0};
    if (!WithinPrior(options, pose.ToPose())) continue;
    if (out.size() >= kScanKept &&
        std::any_of(out.begin(), out.end(), [&](const Candidate& c) { return SamePose(c.pose, pose, width); }))
      continue;
    const double cost = scorer.Cost(pose, cols);
    if (std::isfinite(cost)) out.push_back({pose, cost});
  }
  return out;
}

// Whether a and b look within `tol` (radians) of each other in azimuth and pitch.
bool YawPitchWithin(const Pose4& a, const Pose4& b, double tol) {
  return std::abs(std::remainder(a.yaw - b.yaw, 2 * kPi)) < tol && std::abs(a.pitch - b.pitch) < tol;
}

bool SamePose(const Pose4& a, const Pose4& b, double width) {
  const double hfov = 2.0 * std::atan(0.5 * width / a.f);
  const double tol = std::max(DegToRad(0.5), 0.03 * hfov);
  return YawPitchWithin(a, b, tol) && std::abs(std::log(a.f / b.f)) < 0.05;
}

// Within a tenth of the opening angle (at least 1 deg) and 15% in focal
// length: close enough that, predicting the same skyline, it is the same
// solution half converged (far poses predicting the same skyline are a
// repeating horizon: an ambiguity).
bool NearPose(const Pose4& a, const Pose4& b, double width) {
  const double tol = std::max(DegToRad(1.0), 0.1 * 2.0 * std::atan(0.5 * width / a.f));
  return YawPitchWithin(a, b, tol) && std::abs(std::log(a.f / b.f)) < 0.15;
}

// Smallest and largest cosine of the angle between the rays through two
// image points (offsets from the principal point) for focal lengths in
// [fmin, fmax] (sampled finely on a log grid, widened by a margin for what
// falls between samples).
std::pair<double, double> RayCosineRange(const ImagePoint& p1, const ImagePoint& p2, double fmin, double fmax) {
  const Eigen::Vector2d u1(p1.x, p1.y), u2(p2.x, p2.y);
  double lo = 1.0, hi = -1.0;
  constexpr int kSteps = 48;
  for (int i = 0; i <= kSteps; ++i) {
    const double f = fmin * std::pow(fmax / fmin, static_cast<double>(i) / kSteps), f2 = f * f;
    const double c = (u1.dot(u2) + f2) / std::sqrt((u1.squaredNorm() + f2) * (u2.squaredNorm() + f2));
    lo = std::min(lo, c);
    hi = std::max(hi, c);
  }
  const double margin = 0.02 * (hi - lo) + 1e-9;
  return {lo - margin, hi + margin};
}

// Whether the skyline spans enough of the frame, on both sides of the
// centre, for k1 to be told apart from the focal length and pitch.
bool SpansForDistortion(const std::vector<Column>& all, int width, const RegistrationOptions& o) {
  if (all.size() < 0.5 * width) return false;
  const double lo = all.front().x_px, hi = all.back().x_px;
  return lo <= width * (1.0 - o.distortion_min_span) / 2.0 && hi >= width * (1.0 + o.distortion_min_span) / 2.0;
}

// Final robust fit from `start` with covariance, then the statistics and the
// acceptance tests (the ambiguity ratio must already be in `out`).
void FinishRegistration(const Scorer& scorer, const ImageFrame& frame, std::vector<Column>& all, const Pose4& start,
                        int width, double step, double px_scale, bool fix_focal, const RegistrationOptions& options,
                        const std::vector<double>& anneal, Registration& out) {
  scorer.Reweight(start, all);
  std::vector<Column> final_cols = Subsample(all, options.refine_columns);
  const double hfov_rad = 2.0 * std::atan(0.5 * width / start.f);
  LeastSquaresOptions lso;
  lso.rounds = 3;
  lso.anneal = anneal;
  lso.fix_focal = fix_focal || frame.known();
  lso.want_covariance = true;
  lso.effective_fraction = std::min(1.0, RadToDeg(hfov_rad) / step / final_cols.size());
  lso.fit_k1 = !frame.known() && options.estimate_distortion && SpansForDistortion(all, width, options);
  lso.k1_prior_sigma = options.distortion_prior_sigma;
  Refined fr = RefineLeastSquares(scorer, final_cols, start, lso);
  if (lso.fit_k1) {
    // Reweighted for the fitted pose and lens, once more.
    scorer.Reweight(fr.pose, final_cols);
    lso.anneal.clear();
    lso.rounds = 2;
    fr = RefineLeastSquares(scorer, final_cols, fr.pose, lso);
  }
  const Pose4 bp = fr.pose;
  scorer.Reweight(bp, all);
  const match_detail::FitStats stats = match_detail::ComputeFitStats(scorer, bp, all, width);
  out.pose = bp.ToPose();
  out.focal_px = bp.f;
  out.hfov_deg = HfovFromFocalDeg(bp.f, width);
  out.intrinsics = frame.Intrinsics(bp);
  out.center_ray = CenterRayPose(out.pose, out.intrinsics);
  out.distortion_estimated = lso.fit_k1;
  out.k1_sigma = lso.fit_k1 ? fr.sigma[4] : NAN;
  out.inlier_fraction = stats.inlier_fraction;
  out.informative_columns = stats.informative_columns;
  out.independent_inliers = stats.independent_inliers;
  out.outliers_below = stats.outliers_below;
  out.outliers_above = stats.outliers_above;
  out.hidden_columns = stats.hidden_columns;
  out.unhidden_inlier_fraction = stats.unhidden_inlier_fraction;
  out.rms_px = stats.rms_px;
  out.model_rms_px = stats.model_rms_px;
  const double scale = out.dem.flattening_scale;
  out.dem = stats.dem;
  out.dem.flattening_scale = scale;
  out.azimuth_sigma_deg = RadToDeg(fr.sigma[0]);
  out.pitch_sigma_deg = RadToDeg(fr.sigma[1]);
  out.roll_sigma_deg = RadToDeg(fr.sigma[2]);
  out.focal_sigma_px = fr.sigma[3];
  // Evidence against the best other solution (or, when none was searched,
  // against every column being an outlier): the likelihood ratio, with the
  // cost of each pose's tolerance width (a zoomed-in view that lets every
  // column fit a wide band explains it less), over the independent samples.
  out.misfit = scorer.Misfit(bp, all);
  const double cost = scorer.Cost(bp, all);
  const double second = std::isfinite(out.second_cost) ? out.second_cost : match_detail::kGateChi2;
  out.evidence_nats = stats.independent_inliers * (second - cost) / 2.0;
  std::ostringstream why;
  why.precision(3);
  if (!options.TellsThePose(stats.informative_columns, width))
    why << "the horizon seen is too near or the DEM too coarse to tell the pose (informative columns "
        << std::lround(100.0 * stats.informative_columns / width) << "% of the width)";
  else if (!options.FitsEnough(out.inlier_fraction, out.unhidden_inlier_fraction))
    why << "only " << std::lround(100 * out.inlier_fraction) << "% of the skyline fits the DEM horizon"
        << HiddenShare(stats.hidden_columns, out.unhidden_inlier_fraction, options)
        << MissesSide(stats.outliers_below, stats.outliers_above);
  else if (!(stats.model_rms_px <= options.max_rms_px * px_scale))
    why << "residual " << stats.model_rms_px << " px too large";
  else if (out.ambiguity_ratio < options.min_ambiguity_ratio)
    why << "ambiguous: another pose fits almost as well (cost ratio " << out.ambiguity_ratio << ")";
  else if (out.second_misfit < options.min_misfit_ratio * out.misfit)
    why << "ambiguous: another pose fits the skyline more closely (misfit ratio " << out.second_misfit / out.misfit
        << ")";
  else if (out.evidence_nats < options.min_evidence_nats)
    why << "too little evidence: " << std::lround(out.evidence_nats) << " nats over "
        << std::lround(stats.independent_inliers) << " independent DEM samples (near terrain or a zoomed-in view)";
  else if (!frame.known() && !options.KeepsKnownHfov(out.hfov_deg))
    why << "the skyline fits at an opening angle of " << out.hfov_deg << " deg, outside the one given ("
        << options.min_hfov_deg << "-" << options.max_hfov_deg << " deg searched)";
  else if (lso.fit_k1 && K1AtBound(bp.k1))
    why << kK1AtBoundMessage << bp.k1 << ")";
  out.message = why.str();
  out.registered = out.message.empty();
  if (out.registered) out.message = "registered";
}


constexpr double kMinFlatteningScale = 0.1, kMaxFlatteningScale = 2.0;

// How much of the DEM error model's flattening this image shows at pose p:
// the columns' excess over the DEM horizon in units of the model's
// tolerance, whose median over ln 2 is the scale of an exponential excess;
// within [0.1, 2]. A rendered view of the same DEM hugs it (about 0.1); a
// photo over a coarse DEM stands above its cut peaks (about 1). 1 when too
// few columns have a tolerance worth measuring.
double EstimateFlatteningScale(const Scorer& scorer, const Pose4& p, std::vector<Column> cols) {
  scorer.Reweight(p, cols);
  const Eigen::Matrix3d m = CamFromEnuRad(p.yaw, p.pitch, p.roll);
  std::vector<double> ratios;
  for (const Column& c : cols) {
    if (!(c.flattening_px > 0.5 * scorer.sigma_px())) continue;
    const double r = scorer.Residual(m, p, c);
    if (r > 3.0 * c.noise_px) continue;  // below the DEM horizon by more than the noise: misread, not flattening
    ratios.push_back(std::max(0.0, -r) / c.flattening_px);
  }
  if (ratios.size() < 20) return 1.0;
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  return std::clamp(ratios[ratios.size() / 2] / std::log(2.0), kMinFlatteningScale, kMaxFlatteningScale);
}


}  // namespace

double HorizonDistancePx(const HorizonProfile& horizon, const CameraPose& pose, const CameraIntrinsics& k, double x,
                         double y) {
  const HorizonLookup lookup(horizon, DemErrorModel{});
  const Scorer scorer(lookup, DemErrorModel{}, 1.0, k.height, 0.25);
  const ImageFrame frame(Skyline{k.width, k.height, {}, {}, {}}, k);
  const auto uv = frame.Offset(x, y);
  if (!uv) return NAN;
  std::vector<Column> one(1);
  one[0].u = uv->x();
  one[0].v = uv->y();
  const Pose4 p = Pose4::From(pose, k.focal_px);
  scorer.Reweight(p, one);
  return scorer.Residual(CamFromEnu(pose), p, one[0]);
}

std::vector<double> ProjectedHorizonRows(const HorizonProfile& horizon, const CameraPose& pose,
                                         const CameraIntrinsics& k) {
  k.Check();
  const Eigen::Matrix3d m = CamFromEnu(pose);
  std::vector<double> rows(k.width, NAN);
  for (int c = 0; c < k.width; ++c) {
    const double x = c + 0.5;
    auto above = [&](double y) {
      const AzEl ae = AzElFromEnu(UnprojectToEnu(m, k, {x, y}));
      return ae.elevation_deg - horizon.ElevationAtDeg(ae.azimuth_deg);
    };
    double lo = -2.0 * k.height, hi = 3.0 * k.height;  // sky at lo, terrain at hi
    if (!(above(lo) > 0 && above(hi) < 0)) continue;
    while (hi - lo > 1e-6) {
      const double mid = 0.5 * (lo + hi);
      (above(mid) > 0 ? lo : hi) = mid;
    }
    rows[c] = 0.5 * (lo + hi);
  }
  return rows;
}

Registration Register(const Skyline& skyline, const HorizonProfile& horizon, const RegistrationOptions& options) {
  options.Check();
  if (skyline.width < 1 || static_cast<int>(skyline.y.size()) != skyline.width)
    throw InvalidArgument("Register: skyline has no columns or y.size() != width");
  if (horizon.size() < 8) throw InvalidArgument("Register: horizon profile has fewer than 8 bins");
  const int width = skyline.width;
  const double px_scale = ToleranceScale(width);
  const double tau = options.inlier_px * px_scale;
  Registration out;
  const ImageFrame frame(skyline, options.known_intrinsics);
  std::optional<ThreadPool> own_pool;
  ThreadPool* threads = options.pool;
  if (!threads && options.num_threads > 1) threads = &own_pool.emplace(options.num_threads);

  std::vector<Column> all = VisibleColumns(skyline, frame);
  const double visible = static_cast<double>(all.size()) / width;
  if (visible < options.min_visible_fraction) {
    out.message = "too little skyline visible";
    return out;
  }

  // Extrema: image (up positive, pixels) and DEM horizon (degrees).
  // Extrema of the skyline after a running median over a few columns: a spike
  // one or two columns wide (a pole, a misread pixel run) is not a peak.
  const int half = std::max(2, static_cast<int>(std::lround(4 * px_scale)));
  std::vector<double> up(width, NAN), window;
  for (int i = 0; i < width; ++i) {
    if (!std::isfinite(skyline.MatchY(i))) continue;
    window.clear();
    for (int j = std::max(0, i - half); j <= std::min(width - 1, i + half); ++j)
      if (const double y = skyline.MatchY(j); std::isfinite(y)) window.push_back(y);
    std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
    up[i] = -window[window.size() / 2];
  }
  // Short gaps (columns dropped for low contrast, in haze or JPEG noise)
  // bridged by straight lines: they would split the skyline into runs too
  // short to hold a peak or dip, and a line adds none.
  const int max_gap = std::max(4, static_cast<int>(std::lround(kMaxBridgedGap * width)));
  for (int i = 0, last = -1; i < width; ++i) {
    if (!std::isfinite(up[i])) continue;
    if (last >= 0 && i - last > 1 && i - last - 1 <= max_gap)
      for (int j = last + 1; j < i; ++j) up[j] = up[last] + (up[i] - up[last]) * (j - last) / (i - last);
    last = i;
  }
  ExtremaOptions eo;
  eo.min_prominence = options.min_image_prominence_px * px_scale;
  eo.max_count = options.image_extrema;
  std::vector<Extremum> img = FindExtrema(up, false, eo);
  // Keep the most prominent overall.
  std::sort(img.begin(), img.end(), [](const Extremum& a, const Extremum& b) { return a.prominence > b.prominence; });
  if (static_cast<int>(img.size()) > options.image_extrema) img.resize(options.image_extrema);
  std::sort(img.begin(), img.end(), [](const Extremum& a, const Extremum& b) { return a.position < b.position; });
  // Their points in the fitting's coordinates.
  std::vector<std::optional<Eigen::Vector2d>> img_uv;
  for (const Extremum& e : img) img_uv.push_back(frame.Offset(e.position + 0.5, -e.value));
  ExtremaOptions ho;
  ho.min_prominence = options.min_horizon_prominence_deg;
  ho.max_count = options.horizon_extrema;
  const std::vector<Extremum> dem = FindExtrema(horizon.elevation_deg, true, ho);
  out.image_extrema = static_cast<int>(img.size());
  out.horizon_extrema = static_cast<int>(dem.size());
  // Fewer than two peaks or dips on either side: no pairs, but the azimuth
  // scan below (a gentle ridge seen through a narrow window of opening angles).
  const bool pairable = img.size() >= 2 && dem.size() >= 2;
  const char* kTooFewExtrema = "too few peaks and dips to form hypotheses";
  if (!pairable && !options.scan_plain_skylines) {
    out.message = kTooFewExtrema;
    return out;
  }

  const HorizonLookup lookup(horizon, options.dem_error);
  const Scorer scorer(lookup, options.dem_error, SigmaPx(options, width), skyline.height, options.outlier_share);
  const std::vector<Column> coarse = Subsample(all, options.coarse_columns);
  // Focal lengths searched: the opening-angle range, or the known lens' with
  // room for the extrema's position errors (a DEM peak a few tenths of a
  // degree from the image's, over a pair W/20 apart, ~2.5 deg at a 50-deg
  // opening angle: +-3% lost the right pair on AK10_20090803_195410, +-10%
  // keeps it; the hypothesis then takes the known focal length).
  const double fmin = frame.known() ? frame.KnownFocalPx() / 1.10 : FocalFromHfovPx(options.max_hfov_deg, width);
  const double fmax = frame.known() ? frame.KnownFocalPx() * 1.10 : FocalFromHfovPx(options.min_hfov_deg, width);
  const double step = horizon.azimuth_step_deg;
  auto dem_point = [&](const Extremum& e) { return HorizonPoint{e.position * step, e.value}; };
  std::vector<Eigen::Vector3d> dem_dirs;
  for (const Extremum& e : dem) {
    const double az = DegToRad(e.position * step), el = DegToRad(e.value);
    dem_dirs.emplace_back(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
  }
  auto DirectionOf = [&](const Extremum& e) -> const Eigen::Vector3d& { return dem_dirs[&e - dem.data()]; };

  // Hypotheses: every pair of image extrema far enough apart against every
  // pair of DEM extrema of the same kinds whose angular separation a camera
  // in the opening-angle range could show. The image pairs are shared out
  // among the threads; each keeps its best candidates (pruned against its own
  // 64th best, which only drops hypotheses that cannot be among the best 64).
  struct ImagePair {
    size_t a, b;
  };
  std::vector<ImagePair> pairs;
  const double min_sep = width / 20.0;
  for (size_t a = 0; pairable && a < img.size(); ++a)
    for (size_t b = a + 1; b < img.size(); ++b)
      if (img[b].position - img[a].position >= min_sep && img_uv[a] && img_uv[b]) pairs.push_back({a, b});
  struct Scored {
    std::vector<Candidate> candidates;
    double bound = INFINITY;  // the 64th best cost at the last pruning: an upper bound of the 64th best
    int hypotheses = 0;
  };
  std::vector<Scored> parts(threads ? threads->size() : 1);
  ParallelFor(threads, pairs.size(), [&](size_t k, int t) {
    Scored& result = parts[t];
    std::vector<Candidate>& scored = result.candidates;
    const Extremum &ia = img[pairs[k].a], &ib = img[pairs[k].b];
    const ImagePoint p1{img_uv[pairs[k].a]->x(), img_uv[pairs[k].a]->y()};
    const ImagePoint p2{img_uv[pairs[k].b]->x(), img_uv[pairs[k].b]->y()};
    // The cosines of the angle between the two pixel rays over the focal
    // range: a DEM pair whose angle falls outside cannot be this pair.
    const std::pair<double, double> cos_range = RayCosineRange(p1, p2, fmin, fmax);
    for (const Extremum& da : dem) {
      if (da.is_max != ia.is_max) continue;
      for (const Extremum& db : dem) {
        if (db.is_max != ib.is_max || &da == &db) continue;
        const double sep = WrapAzimuthDeg((db.position - da.position) * step);
        if (sep <= 0.0 || sep > RadToDeg(2.0 * std::atan(0.5 * width / fmin)) + 1.0) continue;
        const double cos_dem = DirectionOf(da).dot(DirectionOf(db));
        if (cos_dem < cos_range.first || cos_dem > cos_range.second) continue;
        for (const PoseHypothesis& hyp : TwoPointPoses(p1, p2, dem_point(da), dem_point(db), 0.0, 0.0, fmin, fmax)) {
          const PoseHypothesis* h = &hyp;
          // An image extremum cannot be more prominent than its DEM match
          // (it is seen through a window of the horizon).
          const double to_deg = RadToDeg(1.0 / h->focal_px);
          if (da.prominence < 0.5 * ia.prominence * to_deg - 0.05 ||
              db.prominence < 0.5 * ib.prominence * to_deg - 0.05)
            continue;
          if (!WithinPrior(options, h->pose)) continue;
          ++result.hypotheses;
          const Pose4 pose = Pose4::From(h->pose, frame.known() ? frame.KnownFocalPx() : h->focal_px);
          const double cost = scorer.Cost(pose, coarse, result.bound);
          if (!std::isfinite(cost)) continue;
          scored.push_back({pose, cost});
          if (scored.size() >= 256) {  // keep the best 64
            std::partial_sort(scored.begin(), scored.begin() + kKeptHypotheses, scored.end(), ByCost);
            scored.resize(kKeptHypotheses);
            result.bound = scored.back().cost;
          }
        }
      }
    }
  });
  std::vector<Candidate> scored;
  for (const Scored& part : parts) {
    out.hypotheses += part.hypotheses;
    scored.insert(scored.end(), part.candidates.begin(), part.candidates.end());
  }
  // A skyline too plain for the pairs: the azimuth scanned as well.
  if (options.scan_plain_skylines && out.hypotheses < kScanBelowHypotheses) {
    const double f0 = frame.known() ? frame.KnownFocalPx() : fmin, f1 = frame.known() ? frame.KnownFocalPx() : fmax;
    const std::vector<Candidate> scan = ScanAzimuths(scorer, lookup, coarse, options, f0, f1, tau, width);
    out.scanned_hypotheses = static_cast<int>(scan.size());
    out.hypotheses += out.scanned_hypotheses;
    scored.insert(scored.end(), scan.begin(), scan.end());
  }
  // The best 64 overall, ties broken by the pose: the same list whichever
  // thread scored which pair.
  std::sort(scored.begin(), scored.end(), ByCost);
  if (scored.size() > kKeptHypotheses) scored.resize(kKeptHypotheses);
  if (scored.empty()) {
    out.message = pairable ? "no hypothesis within the opening-angle range and priors" : kTooFewExtrema;
    return out;
  }

  // Refine the best distinct hypotheses. Stage 1: the paper's linear
  // corrections (eq. 11-14) on a few columns; stage 2: robust least squares,
  // ranked on all columns. The ambiguity needs another solution to compare
  // with: when every refined candidate converges onto the best one, more
  // distinct hypotheses are refined, up to kMaxRefined.
  constexpr size_t kMaxRefined = 16;
  constexpr int kMaxPolishedRivals = 3;  // alternatives refined again before the ambiguity is taken
  std::vector<Column> quick = Subsample(all, options.quick_columns);
  std::vector<Candidate> pool;                 // distinct hypotheses, after stage 1, in the order refined
  std::vector<PaperCorrection> pool_correction;
  size_t next_scored = 0;                      // next coarse hypothesis to consider
  auto extend_pool = [&](size_t count) {
    std::vector<Candidate> fresh;
    while (fresh.size() < count && next_scored < scored.size()) {
      const Candidate& c = scored[next_scored++];
      auto same = [&](const Candidate& d) { return SamePose(d.pose, c.pose, width); };
      if (std::none_of(pool.begin(), pool.end(), same) && std::none_of(fresh.begin(), fresh.end(), same))
        fresh.push_back(c);
    }
    std::vector<PaperCorrection> corr(fresh.size());
    ParallelFor(threads, fresh.size(), [&](size_t i, int) {
      Candidate& c = fresh[i];
      PaperCorrection pc = CorrectLinear(scorer, quick, c.pose, width, tau);
      if (frame.known()) pc.pose.f = c.pose.f;
      const double corrected = scorer.Cost(pc.pose, quick);
      c.cost = scorer.Cost(c.pose, quick);
      if (corrected < c.cost) c = {pc.pose, corrected};
      corr[i] = pc;
    });
    std::vector<size_t> by_cost(fresh.size());
    std::iota(by_cost.begin(), by_cost.end(), 0);
    std::sort(by_cost.begin(), by_cost.end(), [&](size_t x, size_t y) { return fresh[x].cost < fresh[y].cost; });
    for (size_t k : by_cost) pool.push_back(fresh[k]), pool_correction.push_back(corr[k]);
  };
  std::vector<Candidate> refined;
  std::vector<PaperCorrection> corrections;
  // A narrow window of opening angles (a known --hfov, +-3%; --initial's
  // +-5%) holds about one distinct hypothesis per solution (the others are
  // SamePose, within 5% of focal length), refined from that one start; a
  // wide window's hypotheses of one solution differ in focal length and
  // start it several times. From one start, AKJNC_20120813 with its true
  // opening angle ended in a local minimum 0.25 deg and 1.5% of focal
  // length off (cost 5.35 against 3.62: ambiguous), and a wrong position's
  // candidates, refined as poorly, let a ring probe of AK01b_20080811
  // register 164 deg off. So each candidate is also refined from its focal
  // length 3% longer and shorter, the least cost kept
  // (RegistrationOptions::narrow_window_restarts).
  const bool multi_start = !frame.known() && options.narrow_window_restarts && options.NarrowHfovWindow();
  // A refined pose is kept inside the priors and (near) the window of opening angles.
  auto admitted = [&](const Pose4& q) {
    if (!WithinPrior(options, q.ToPose())) return false;
    const double hfov = HfovFromFocalDeg(q.f, width);
    return frame.known() || options.AdmitsHfov(hfov);
  };
  auto refine_pool = [&](size_t from, size_t to) {
    std::vector<std::optional<Candidate>> slots(to - from);
    ParallelFor(threads, to - from, [&](size_t k, int) {
      const Candidate& c = pool[from + k];
      LeastSquaresOptions lso;
      lso.rounds = 2;
      lso.anneal = {6.0, 3.0};  // candidates a few pixels off converge; neighbours of one solution merge
      lso.fix_focal = frame.known();
      lso.bound_focal = options.bound_search_focal;
      auto refined_from = [&](const Pose4& start) {
        std::vector<Column> cols = quick;  // weighted for this start
        scorer.Reweight(start, cols);
        return RefineLeastSquares(scorer, cols, start, lso).pose;
      };
      Candidate rc{refined_from(c.pose), 0.0};
      bool kept = admitted(rc.pose);
      if (multi_start) {
        double least = kept ? scorer.Cost(rc.pose, quick) : INFINITY;
        for (const double factor : {kFocalStartFactor, 1.0 / kFocalStartFactor}) {
          Pose4 start = c.pose;
          start.f *= factor;
          const Pose4 more = refined_from(start);
          if (!admitted(more)) continue;
          if (const double q = scorer.Cost(more, quick); q < least) least = q, rc.pose = more;
        }
        kept = std::isfinite(least);
      }
      if (!kept) return;
      const CameraPose cp = rc.pose.ToPose();
      rc.cost = scorer.Cost(rc.pose, all) + 0.02 * PriorPenalty(options.prior, cp);
      rc.inliers = scorer.InlierShare(rc.pose, all);
      rc.misfit = scorer.Misfit(rc.pose, all);
      slots[k] = rc;
    });
    for (size_t k = 0; k < slots.size(); ++k)
      if (slots[k]) refined.push_back(*slots[k]), corrections.push_back(pool_correction[from + k]);
  };
  // The best refined candidate and the best alternative that is another
  // solution: one whose predicted skyline differs from the best's (a
  // half-converged copy of the best, a few tenths of a degree and percent
  // of focal length away, predicts the same skyline and is no alternative).
  // Compared on the cost, as the best is chosen: a pose that lets every
  // column fit a wide band (a zoomed-in view, near terrain) pays for its
  // tolerance and is no rival for a close fit (on the misfit alone such a
  // pose beat the correct one on three of the real photos' traced skylines).
  std::vector<size_t> order;
  const Candidate* second_candidate = nullptr;
  const Candidate* closest_rival = nullptr;  // the distinct alternative of least misfit
  std::vector<uint8_t> merged;               // polished onto the best: no alternative
  auto same_solution = [&](const Pose4& c, const Pose4& b) {
    return SamePose(c, b, width) || (NearPose(c, b, width) && scorer.Agreement(c, b, quick, tau) >= 0.5);
  };
  auto rank = [&] {
    merged.resize(refined.size(), 0);
    order.resize(refined.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return refined[x].cost < refined[y].cost; });
    second_candidate = nullptr;
    closest_rival = nullptr;
    if (refined.empty()) return;
    const Candidate& b = refined[order[0]];
    for (size_t i = 1; i < order.size(); ++i) {
      const Candidate& c = refined[order[i]];
      if (merged[order[i]] || same_solution(c.pose, b.pose) || options.RulesOut(c.pose.ToPose())) continue;
      if (!second_candidate || c.cost < second_candidate->cost) second_candidate = &c;
      if (!closest_rival || c.misfit < closest_rival->misfit) closest_rival = &c;
    }
  };
  extend_pool(options.candidates);
  size_t refined_upto = std::min(pool.size(), static_cast<size_t>(options.refined_candidates));
  refine_pool(0, refined_upto);
  rank();
  while (!second_candidate && refined_upto < kMaxRefined && !options.search_only) {
    if (refined_upto >= pool.size()) extend_pool(options.refined_candidates);
    if (refined_upto >= pool.size()) break;  // no more distinct hypotheses
    const size_t to = std::min({pool.size(), refined_upto + static_cast<size_t>(options.refined_candidates), kMaxRefined});
    refine_pool(refined_upto, to);
    refined_upto = to;
    rank();
  }
  if (refined.empty()) {
    out.message = "no refined hypothesis within the opening-angle range and priors";
    return out;
  }
  auto reported = [](const Candidate& c) { return PoseCandidate{c.pose.ToPose(), c.pose.f, c.cost, c.inliers}; };
  for (size_t i : order) out.candidates.push_back(reported(refined[i]));
  if (options.search_only) {
    out.message = "search only";
    return out;
  }
  // An alternative must be a minimum of its own. The candidates were refined
  // on a few columns and rounds; one left half-way down the best's slope
  // (CG05_20050811_130000 in grey: 1 deg and 5% of focal length off the
  // best, 57% of its columns in the gate against 93%) is refined again on
  // all columns, annealed from a wider noise scale. When it then predicts
  // the best's skyline it is dropped and the next is tried; one that stays
  // apart is the alternative as it was found (taking its polished pose, a
  // lower cost, refused the re-encoded AK01b_20080811: 1.41 -> 1.40).
  for (int tries = 0; second_candidate && tries < kMaxPolishedRivals; ++tries) {
    const size_t k = static_cast<size_t>(second_candidate - refined.data());
    const Candidate& rival = refined[k];
    const Pose4& b = refined[order[0]].pose;
    // Only a rival within the refinement's reach of the best can converge
    // onto it (polishing every rival, however far, cost 14-18 ms more per
    // registration of the benchmark's dev scenes, on 2 threads; within a
    // quarter of the opening angle none of theirs is polished).
    if (!YawPitchWithin(rival.pose, b, 0.25 * 2.0 * std::atan(0.5 * width / b.f))) break;
    std::vector<Column> cols = all;
    scorer.Reweight(rival.pose, cols);
    LeastSquaresOptions lso;
    lso.rounds = 3;
    lso.anneal = {12.0, 6.0, 3.0};
    lso.fix_focal = frame.known();
    const Pose4 p = RefineLeastSquares(scorer, cols, rival.pose, lso).pose;
    if (admitted(p) && same_solution(p, b)) {
      merged[k] = 1;
      rank();
      continue;
    }
    break;
  }
  const Candidate& best = refined[order[0]];
  // The DEM's flattening as the best pose shows it; the best and its
  // alternative are then judged alike under it (a view rendered from the
  // DEM itself leaves a wrong pose no slack the data did not ask for).
  const double scale = EstimateFlatteningScale(scorer, best.pose, quick);
  const DemErrorModel adapted = ScaledModel(options.dem_error, scale);
  const HorizonLookup adapted_lookup(horizon, adapted);
  const Scorer adapted_scorer(adapted_lookup, adapted, SigmaPx(options, width), skyline.height, options.outlier_share);
  out.dem.flattening_scale = scale;
  const double best_cost = adapted_scorer.Cost(best.pose, all);
  if (second_candidate) {
    out.second_cost = adapted_scorer.Cost(second_candidate->pose, all);
    out.second_inlier_fraction = adapted_scorer.InlierShare(second_candidate->pose, all);
    out.second_misfit = adapted_scorer.Misfit(closest_rival->pose, all);
    out.rival = reported(*second_candidate);
  }
  out.ambiguity_ratio = second_candidate ? out.second_cost / std::max(best_cost, 1e-9) : INFINITY;
  out.ex_px = corrections[order[0]].ex_px;
  out.ey_px = corrections[order[0]].ey_px;
  FinishRegistration(adapted_scorer, frame, all, best.pose, width, step, px_scale, false, options, {}, out);
  return out;
}

Registration RefinePose(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start, double focal_px,
                        bool fix_focal, const RegistrationOptions& options, double start_noise_px) {
  options.Check();
  if (skyline.width < 1 || static_cast<int>(skyline.y.size()) != skyline.width)
    throw InvalidArgument("RefinePose: skyline has no columns or y.size() != width");
  if (horizon.size() < 8) throw InvalidArgument("RefinePose: horizon profile has fewer than 8 bins");
  if (!(focal_px > 0.0)) throw InvalidArgument("RefinePose: focal_px must be > 0");
  if (!(start_noise_px > 0.0)) throw InvalidArgument("RefinePose: start_noise_px must be > 0");
  const int width = skyline.width;
  const double px_scale = ToleranceScale(width);
  Registration out;
  const ImageFrame frame(skyline, options.known_intrinsics);
  std::vector<Column> all = VisibleColumns(skyline, frame);
  if (static_cast<double>(all.size()) / width < options.min_visible_fraction || all.size() < 8) {
    out.message = "too little skyline visible";
    return out;
  }
  const HorizonLookup lookup(horizon, options.dem_error);
  const double sigma = SigmaPx(options, width);
  const Scorer scorer(lookup, options.dem_error, sigma, skyline.height, options.outlier_share);
  // Graduated noise: from start_noise_px (per 1000 px) down to sigma in
  // halvings, so that a start tens of pixels off still finds its basin.
  std::vector<double> anneal;
  for (double s = start_noise_px * px_scale / sigma; s > 1.5; s /= 2.0) anneal.push_back(s);
  out.ambiguity_ratio = INFINITY;  // not searched: the start pose is given
  const double f = frame.known() ? frame.KnownFocalPx() : focal_px;
  // A first fit under the prior DEM error model, then the flattening this
  // image shows there, then the final fit and decision under it.
  std::vector<Column> cols = Subsample(all, options.quick_columns);
  scorer.Reweight(Pose4::From(start, f), cols);
  LeastSquaresOptions lso;
  lso.rounds = 2;
  lso.anneal = anneal;
  lso.fix_focal = fix_focal || frame.known();
  const Pose4 first = RefineLeastSquares(scorer, cols, Pose4::From(start, f), lso).pose;
  const double scale = EstimateFlatteningScale(scorer, first, cols);
  const DemErrorModel adapted = ScaledModel(options.dem_error, scale);
  const HorizonLookup adapted_lookup(horizon, adapted);
  const Scorer adapted_scorer(adapted_lookup, adapted, sigma, skyline.height, options.outlier_share);
  out.dem.flattening_scale = scale;
  FinishRegistration(adapted_scorer, frame, all, first, width, horizon.azimuth_step_deg, px_scale, fix_focal, options, {},
                     out);
  return out;
}

constexpr double kMinPrincipalGainNats = 3.0;
constexpr double kMaxPrincipalMoveDeg = 1.0;

Registration RefinePrincipalColumn(const Skyline& skyline, const HorizonProfile& horizon, const Registration& reg,
                                   const RegistrationOptions& options) {
  options.Check();
  const int width = skyline.width;
  if (!reg.registered || options.known_intrinsics || !(options.principal_point_range > 0.0) || width < 8 ||
      static_cast<int>(skyline.y.size()) != width || horizon.size() < 8 || !(reg.focal_px > 0.0))
    return reg;
  const ImageFrame frame(skyline, std::nullopt);
  const std::vector<Column> centred = VisibleColumns(skyline, frame);
  if (centred.size() < 8) return reg;
  const DemErrorModel model = std::isfinite(reg.dem.flattening_scale)
                                  ? ScaledModel(options.dem_error, reg.dem.flattening_scale)
                                  : options.dem_error;
  const HorizonLookup lookup(horizon, model);
  const Scorer scorer(lookup, model, SigmaPx(options, width), skyline.height, options.outlier_share);
  const CameraIntrinsics k0 = reg.Intrinsics(width, skyline.height);
  const double k1 = reg.distortion_estimated ? k0.distortion.k()[0] : 0.0;
  // The registration's centre ray: every offset's fit starts from the
  // camera that sees it through the image's centre.
  const CameraPose center = CenterRayPose(reg.pose, k0);
  struct Fit {
    double dx = 0.0, cost = INFINITY;
    Pose4 pose;
  };
  auto fit_at = [&](double dx) {
    Fit out;
    out.dx = dx;
    std::vector<Column> cols = centred;
    for (Column& c : cols) c.u -= dx;
    CameraIntrinsics k = k0;
    k.cx_px = width / 2.0 + dx;
    const Pose4 start = Pose4::From(AxisPoseFromCenterRay(center, k), reg.focal_px, k1);
    scorer.Reweight(start, cols);
    std::vector<Column> sub = Subsample(cols, options.refine_columns);
    // k1 refitted with the centre (held at the centred fit's, it keeps
    // what that fit made of the offset: a synthetic crop's centre found 65
    // px short); the guards below catch the two trading off.
    LeastSquaresOptions lso;
    lso.rounds = 3;
    lso.fit_k1 = reg.distortion_estimated;
    lso.k1_prior_sigma = options.distortion_prior_sigma;
    out.pose = RefineLeastSquares(scorer, sub, start, lso).pose;
    scorer.Reweight(out.pose, cols);
    out.cost = scorer.Cost(out.pose, cols);
    return out;
  };
  const double range = options.principal_point_range * width, step = width / 40.0;
  std::vector<Fit> fits;
  for (double dx = -std::floor(range / step) * step; dx <= range + 1e-9; dx += step) fits.push_back(fit_at(dx));
  if (fits.size() < 3) return reg;
  const auto best = std::min_element(fits.begin(), fits.end(), [](const Fit& a, const Fit& b) { return a.cost < b.cost; });
  Fit chosen = *best;
  if (best != fits.begin() && best + 1 != fits.end()) {
    const double a = (best - 1)->cost, b = best->cost, c = (best + 1)->cost, den = a - 2.0 * b + c;
    if (den > 0.0) {
      const Fit vertex = fit_at(best->dx + 0.5 * step * (a - c) / den);
      if (vertex.cost < chosen.cost) chosen = vertex;
    }
  }
  // An offset must explain the skyline clearly better than the centre
  // (the cost is a mean chi^2 per column: the gain over the independent
  // samples, in nats): where the DEM's errors swamp the tangent's curvature
  // (a near mountain on a 100 m DEM) the cost is flat to a few percent and
  // its least is noise.
  const auto centre = std::min_element(fits.begin(), fits.end(),
                                       [](const Fit& a, const Fit& b) { return std::abs(a.dx) < std::abs(b.dx); });
  const double gain_nats = 0.5 * (centre->cost - chosen.cost) * reg.independent_inliers;
  if (!std::isfinite(chosen.cost) || !(gain_nats >= kMinPrincipalGainNats)) return reg;
  Registration out = reg;
  out.pose = chosen.pose.ToPose();
  out.focal_px = chosen.pose.f;
  out.hfov_deg = HfovFromFocalDeg(chosen.pose.f, width);
  CameraIntrinsics k = frame.Intrinsics(chosen.pose);
  k.cx_px = width / 2.0 + chosen.dx;
  out.intrinsics = k;
  out.center_ray = CenterRayPose(out.pose, out.intrinsics);
  // The refit corrects the tangent's curvature, a fraction of a degree: one
  // that moves the centre ray further or leaves the opening angles searched
  // is not that correction, and the registration stays as decided (a
  // half-width crop's centre put at its edge with k1 at its bound of 0.6
  // moved it 1.4 deg, off the truth by as much).
  if (std::abs(AngDiffDeg(out.center_ray.azimuth_deg, reg.center_ray.azimuth_deg)) > kMaxPrincipalMoveDeg ||
      std::abs(out.center_ray.pitch_deg - reg.center_ray.pitch_deg) > kMaxPrincipalMoveDeg ||
      !options.AdmitsHfov(out.hfov_deg))
    return reg;
  // The skyline explained clearly best with the lens at its bound: as in
  // the registration (K1AtBound), no camera's.
  if (reg.distortion_estimated && K1AtBound(chosen.pose.k1)) {
    Registration refused = reg;
    refused.registered = false;
    std::ostringstream why;
    why.precision(3);
    why << kK1AtBoundMessage << chosen.pose.k1 << ", the camera's centre searched)";
    refused.message = why.str();
    return refused;
  }
  return out;
}

}  // namespace horizonreg
