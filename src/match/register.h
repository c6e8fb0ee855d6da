// SPDX-License-Identifier: MIT
// Registration (paper, sections 3.2-3.3): camera azimuth, pitch, roll and
// focal length from the image skyline and the 360-degree DEM horizon, with
// no calibration and no initial orientation, and an honest "no match".
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "skyline/skyline.h"
#include "util/thread_pool.h"

namespace horizonreg {

// Compass and inclinometer readings used as priors (DESIGN.md "Sensor
// readings"). Any field may be absent.
struct SensorPrior {
  std::optional<double> compass_deg;    // azimuth of the optical axis, degrees
  std::optional<double> pitch_deg;      // inclinometer pitch, degrees
  std::optional<double> roll_deg;       // inclinometer roll, degrees (conventions.h)
  double compass_sigma_deg = 15.0;      // 1-sigma compass error (phones: 5-30 deg), > 0
  double inclinometer_sigma_deg = 2.0;  // 1-sigma inclinometer error, > 0
  double gate_sigmas = 3.0;             // Hypotheses farther than this many sigmas are dropped, > 0.
  void Check() const;
};

// How far the DEM horizon can be from the true one at each azimuth bin, and
// how the observer's position moves it (issue: real DEMs are coarse). The
// model is one-sided: a grid of posts cuts sharp peaks and ridges, so the
// true horizon lies *above* the DEM's by up to
//   flattening(bin) = hypot(flattening_spacings * spacing / d, flattening_floor)
// (radians; spacing the DEM post spacing there, d the distance), rarely
// below it. The observer's position and eye height add a symmetric
// uncertainty hypot(position_sigma_m, height_sigma_m) / d, largest for near
// terrain. Used in the residual weights, the inlier gate and the no-match
// decision (match/fit_model.h, ColumnLoss).
struct DemErrorModel {
  double flattening_spacings = 0.15;  // mean height deficit of the horizon terrain, in post spacings, >= 0
  double flattening_floor_deg = 0.03; // mean deficit however fine the DEM (snow, sub-grid relief), degrees, >= 0
  // The slope (HorizonProfile::relief_slope) at which the deficit is
  // flattening_spacings; it grows with the slope (a sharp crest between
  // posts stands above them by up to slope x spacing / 2, a dome's by
  // little), within [1/4, 4] times. > 0.
  double typical_slope = 0.4;
  double position_sigma_m = 1.0;       // horizontal position of the observer, 1 sigma, metres, >= 0
  double height_sigma_m = 1.0;         // eye height, 1 sigma, metres, >= 0
  void Check() const;                  // Throws InvalidArgument naming the field.
};

struct RegistrationOptions {
  double min_hfov_deg = 10.0;  // Horizontal opening angles searched, degrees, 0 < min <= max < 170.
  double max_hfov_deg = 120.0;
  // Known intrinsics (focal length, principal point, distortion; any image
  // size, rescaled to the skyline's): used exactly, the focal length is not
  // fitted and min/max_hfov_deg are ignored.
  std::optional<CameraIntrinsics> known_intrinsics;
  // Without known intrinsics: fit radial distortion k1 (about the image
  // centre) in the final refinement when the skyline spans at least
  // `distortion_min_span` of the image width on both sides of the centre.
  bool estimate_distortion = true;
  double distortion_min_span = 0.6;  // share of the width, in [0, 1]
  double distortion_prior_sigma = 0.15;  // k1's prior 1-sigma about 0 (keeps short skylines sane), > 0
  // Without known intrinsics: how far the principal point may lie from the
  // image's centre column, a share of the width in [0, 0.5] (0: at the
  // centre). A photo cropped after it was taken has its camera's centre
  // anywhere over the part cut off (sensors.h FrameOf); RefinePrincipalColumn
  // then searches it.
  double principal_point_range = 0.0;
  double max_abs_roll_deg = 30.0;        // Hypotheses with more roll are dropped (without an inclinometer), degrees.
  int image_extrema = 7;                 // Most prominent image peaks and dips paired into hypotheses, >= 2.
  int horizon_extrema = 70;              // Most prominent DEM peaks and dips of each kind, >= 2.
  double min_image_prominence_px = 1.5;  // Image extrema below this are noise, pixels (scaled up for large images).
  double min_horizon_prominence_deg = 0.03;  // DEM extrema below this are noise, degrees.
  // Where the pairs of peaks and dips give fewer than 16 hypotheses (a
  // gentle ridge, a skyline mostly hidden behind near trees), the azimuth is
  // also scanned: every 0.2 deg at each focal length of a narrow window of
  // opening angles (or of any window when a compass bounds the azimuths),
  // the pitch and roll fitted to each, the best 32 local minima and up to 32
  // more distinct poses (the rivals) scored as the pairs' hypotheses are.
  bool scan_plain_skylines = true;
  int coarse_columns = 24;                   // Skyline columns scored per hypothesis, >= 8.
  int quick_columns = 120;                   // Skyline columns for refining candidates, >= 8.
  int refine_columns = 300;                  // Skyline columns in the final least squares, >= 8.
  int candidates = 8;                        // Distinct best hypotheses given the paper's linear corrections, >= 2.
  int refined_candidates = 8;                // ... of which the best this many get the least squares, >= 2.
  // Pixel noise of the skyline (3 sigma), pixels per 1000 px of image width
  // (ToleranceScale): the inlier gate is 3 sigma of each column's noise,
  // widened by the DEM error model.
  double inlier_px = 3.0;
  double outlier_share = 0.25;  // prior share of misread columns in the robust fit, in (0, 1)
  DemErrorModel dem_error;
  int num_threads = 2;  // Threads scoring and refining hypotheses, >= 1 (same result for any count).
  ThreadPool* pool = nullptr;  // A shared pool to run on instead (then num_threads is unused; same result).
  // The no-match decision (a wrong pose reported as registered is the worst outcome):
  double min_visible_fraction = 0.15;      // of the image columns with a skyline value
  double min_informative_fraction = 0.3;   // of the width: columns whose tolerance lets them inform (near terrain
                                           // and a coarse DEM count little, Registration::informative_columns)
  double min_inlier_fraction = 0.65;       // of the informative columns inside the gate at the refined pose
  // Or this share with the misses hidden by something in front left out
  // (Registration::hidden_columns): a pose that explains part of the
  // skyline away must fit the rest more closely.
  double min_unhidden_inlier_fraction = 0.8;
  bool FitsEnough(double inlier_fraction, double unhidden_inlier_fraction) const {
    return inlier_fraction >= min_inlier_fraction || unhidden_inlier_fraction >= min_unhidden_inlier_fraction;
  }
  double max_rms_px = 1.4;                 // RMS of the inliers' residuals beyond the DEM model (per 1000 px of width)
  double min_ambiguity_ratio = 1.4;        // the best other solution's cost over the best's
  // The least misfit of a distinct alternative over the best's, below which
  // the best is refused: a rival that fits the skyline more closely but pays
  // for a wider tolerance (a zoomed-in view) is not outweighed by the cost
  // alone. Correct poses on the real photos: >= 0.885; a wrong position
  // (zion_01 from 2 km): 0.69.
  double min_misfit_ratio = 0.8;
  // Log-likelihood (nats) by which the best pose beats the best other
  // solution, over the independent DEM samples behind its inliers
  // (Registration::evidence_nats): many columns on a few DEM cells (near
  // terrain, a zoomed-in view) are weak evidence however well they fit.
  double min_evidence_nats = 40.0;
  SensorPrior prior;
  // Search only: rank the refined candidates and return them (no search for
  // a distinct rival, no final fit, registered stays false). For comparing
  // the best cost of one skyline over horizons from several places
  // (pipeline/position_check.h).
  bool search_only = false;
  // In a narrow window of opening angles (max / min < 1.12: a known --hfov,
  // --initial's +-5%), refine each candidate from its focal length 3% longer
  // and shorter too (Register): one distinct hypothesis per solution is
  // refined there, from one start. Off where many places' registrations are
  // only compared with each other (the position check, locate's places),
  // which then cost what they did, not three times as much.
  bool narrow_window_restarts = true;
  // The search's refinements keep the focal length within 0.2-5 times the
  // hypothesis's (LeastSquaresOptions::bound_focal). Off where many places'
  // searches are only compared with each other (the position check): the
  // bound never binds there, and without it Ceres skips the projected line
  // search of every step, a fifth of the check's time. On for a
  // registration's own search: the minima move by rounding (hundredths of a
  // degree), which flips decisions at their gates both ways (measured on
  // 2026-12-06: the grey AK01b_20080811 ambiguous at 1.40, the rendered
  // hard scenes 5 -> 6 of 6), so it stays as measured.
  bool bound_search_focal = true;
  // Poses an image cue has told apart from the best one (the inner ridges
  // of pipeline/ridge_check.h): a candidate within kRuledOutDeg of one in
  // azimuth and pitch is no alternative (neither the ambiguity ratio's nor
  // the misfit ratio's, nor the evidence's). Empty: every distinct
  // candidate is one.
  std::vector<CameraPose> ruled_out_rivals;
  static constexpr double kRuledOutDeg = 1.0;
  // Whether poses a and b lie within kRuledOutDeg of each other in azimuth
  // and pitch (the same pose, for ruling out).
  static bool WithinRuledOutDeg(const CameraPose& a, const CameraPose& b);
  // Whether `pose` lies within kRuledOutDeg of one of ruled_out_rivals.
  bool RulesOut(const CameraPose& pose) const;
  void Check() const;  // Throws InvalidArgument naming the field.
  // Whether the window of opening angles is narrow: max / min < 1.12 (a
  // known --hfov, --initial's +-5%).
  bool NarrowHfovWindow() const { return max_hfov_deg < 1.12 * min_hfov_deg; }
  // Whether the opening angle is as good as known: known intrinsics, or a
  // narrow window. Then no rival at another opening angle can refuse a
  // wrong pose.
  bool OpeningAngleKnown() const { return known_intrinsics.has_value() || NarrowHfovWindow(); }
  // Whether an opening angle is one the search admits: the window and 5%
  // beyond it (a refined focal length may drift a little past its edge).
  bool AdmitsHfov(double hfov_deg) const { return hfov_deg >= min_hfov_deg * 0.95 && hfov_deg <= max_hfov_deg * 1.05; }
  // Whether a registration's opening angle keeps to the window searched:
  // inside a narrow window (NarrowHfovWindow: --hfov, --initial) within 1%,
  // where the candidates may stray 5% (AdmitsHfov) on their way to the best
  // fit; inside a wider one (the EXIF's +-10%, --hfov-range, the default
  // 10-120 deg) with no slack. A fit that leaves the angle given
  // contradicts it: measured on the real photos given their true angle,
  // the registrations stay within 1.2% of it, and from 5 km beside
  // AK01b_20080811 without an altitude a pose 164 deg off registered at
  // +6.8% with its lens bent to k1 = +0.13 (the truth's -0.06). The real
  // photos and their copies registered at their stations fit within 6.4%
  // of their EXIF's angle (the half-width crop of AK01_20070922; the photos
  // as taken and their photometric and re-encoded copies within 4.6%); the
  // half-size copy of AK01b_20100602 given a place 2 km away at 60 deg
  // (eval_real.py --modes ring-downscale2) fitted 11.0% wide, past the
  // EXIF window's edge (58.88 against 58.34 deg), and registered 1.9 deg
  // off, a place the position check's wide look found no better one than.
  // (2026-12-03.)
  static constexpr double kKnownHfovSlack = 0.01;
  bool KeepsKnownHfov(double hfov_deg) const {
    const double slack = NarrowHfovWindow() ? kKnownHfovSlack : 0.0;
    return hfov_deg >= min_hfov_deg * (1.0 - slack) && hfov_deg <= max_hfov_deg * (1.0 + slack);
  }
  // Whether `informative_columns` (Registration::informative_columns) of a
  // skyline `width` columns wide are enough to tell the pose.
  bool TellsThePose(double informative_columns, int width) const {
    return informative_columns >= min_informative_fraction * width;
  }
};

// How much the DEM limited the fit (register JSON "dem"): at the final pose,
// over the inlier columns.
struct DemLimits {
  double post_spacing_m = NAN;          // median DEM post spacing at the horizon points seen
  double horizon_distance_m = NAN;      // median distance of the horizon points seen
  double expected_flattening_px = NAN;  // median of the model's one-sided tolerance
  double skyline_above_dem_px = NAN;    // median of how far the skyline stands above the DEM horizon
  double dem_explained_fraction = NAN;  // share of the inliers that fit only through the DEM's flattening
  double flattening_scale = NAN;        // the DEM error model's flattening as this image shows it (0.1-2)
};

// A refined candidate pose of the search (the best first).
struct PoseCandidate {
  CameraPose pose;
  double focal_px = 0.0;
  double cost = 0.0;             // mean truncated cost over the visible columns (lower is better)
  double inlier_fraction = 0.0;  // share of the visible columns inside the gate
};

struct Registration {
  bool registered = false;
  std::string message;  // why not registered, or a short summary
  CameraPose pose;      // optical axis; meaningful when a best pose exists (also for no_match, for diagnosis)
  CameraPose center_ray;  // the ray through the image centre (= pose for a centred pinhole)
  double focal_px = 0.0;
  double hfov_deg = 0.0;
  // The camera as fitted (known intrinsics, or a centred pinhole with the
  // fitted focal length and k1), for the skyline's image size.
  CameraIntrinsics intrinsics;
  bool distortion_estimated = false;  // k1 was fitted (intrinsics.distortion.k()[0])
  double k1_sigma = NAN;
  double rms_px = NAN;  // RMS residual of the inlier columns (raw, before the DEM model)
  double model_rms_px = NAN;  // the inliers' residuals against what the noise and DEM model expect, as a pixel RMS
  double inlier_fraction = 0.0;         // share of the visible columns inside the gate (near columns count less)
  double ex_px = NAN, ey_px = NAN;      // paper eq. (13), (14): RMS horizontal and vertical differences
  double ambiguity_ratio = 0.0;         // cost of the best distinct alternative over the best's (inf if none)
  double second_inlier_fraction = 0.0;  // share of the columns that alternative fits
  double misfit = NAN, second_misfit = NAN;  // mean truncated chi^2 of the best and of the closest distinct alternative
  double second_cost = NAN;                  // that alternative's mean cost (chi^2 and tolerance width)
  double informative_columns = 0.0;  // columns whose tolerance lets them inform (near terrain counts little)
  double independent_inliers = 0.0;  // independent DEM samples behind the inliers (FitStats)
  int outliers_below = 0, outliers_above = 0;  // outlier columns: the skyline below / above the DEM horizon
  // Of outliers_above, the columns in runs that rise out of the fitted
  // skyline (hidden by something nearer than the DEM shows: a tree, a roof,
  // a cap cloud), and the inlier share with them left out
  // (RegistrationOptions::FitsEnough).
  int hidden_columns = 0;
  double unhidden_inlier_fraction = 0.0;
  // independent_inliers * (second_cost - cost) / 2 (second_cost = 9, all
  // outliers, when nothing else was searched): nats in favour of the pose.
  double evidence_nats = 0.0;
  double azimuth_sigma_deg = NAN, pitch_sigma_deg = NAN, roll_sigma_deg = NAN, focal_sigma_px = NAN;
  DemLimits dem;
  std::vector<PoseCandidate> candidates;  // the refined candidates of the search, best first (empty for RefinePose)
  std::optional<PoseCandidate> rival;     // the distinct alternative the ambiguity ratio is taken against (search only)
  int hypotheses = 0;  // hypotheses scored after the constraints
  int scanned_hypotheses = 0;  // of those, from the azimuth scan (RegistrationOptions::scan_plain_skylines)
  int image_extrema = 0, horizon_extrema = 0;
  // intrinsics for an image of this size (the registered one or a resized copy).
  CameraIntrinsics Intrinsics(int width, int height) const;
};

// The factor of the pixel tolerances (inlier_px, max_rms_px) for an image
// `width` pixels wide: per 1000 px, at least 1.
double ToleranceScale(int width);

// Registers a skyline (skyline module) against a horizon profile computed at
// the camera's position. Extrema of both (match/extrema.h); hypotheses from
// pairs of them (paper eq. 5, 6, 8, 9, generalised to roll by the exact
// two-point solution in match/hypothesis.h), pruned by the opening-angle
// range and the priors; the robust error of eq. (10) over the visible
// columns; the linear corrections of eq. (11)-(14); then a robust (Cauchy)
// least-squares fit of azimuth, pitch, roll and focal length with the exact
// pinhole projection (Ceres), with sigmas from its covariance. Deterministic.
// Throws InvalidArgument for bad options or an empty skyline/profile.
// Thread-safe.
Registration Register(const Skyline& skyline, const HorizonProfile& horizon, const RegistrationOptions& options);

// Refines a pose known approximately (the previous frame's, a fixed
// camera's, a pose a few degrees off) against the skyline, without any
// hypothesis search: a graduated robust least squares (the noise scale
// shrinks from `start_noise_px` per 1000 px of width to the options' over
// four stages, so a start tens of pixels off converges), then the same
// statistics and acceptance tests as Register (no ambiguity test: nothing
// else was searched). `fix_focal` keeps focal_px (known intrinsics keep
// theirs anyway). Throws InvalidArgument for bad options or inputs.
// Thread-safe.
Registration RefinePose(const Skyline& skyline, const HorizonProfile& horizon, const CameraPose& start, double focal_px,
                        bool fix_focal, const RegistrationOptions& options, double start_noise_px = 1.0);

// A registration whose principal point may lie off the image's centre
// column (options.principal_point_range > 0, no known intrinsics): the
// final fit (pose, focal length, k1) again with the principal point at
// offsets over that range (steps of 1/40 of the width, then a parabola
// through the least cost and its neighbours), the least cost kept. On a crop
// the camera's centre is not the image's: fitted as centred, the tangent's
// curvature about the wrong column biases the centre ray by 0.2-0.6 deg
// (a quarter of the width cut off). Kept only when it explains the skyline
// clearly better than the centre (3 nats over the independent samples:
// over a coarse DEM's near terrain the cost is flat to a few percent), the
// centre ray moved by at most 1 deg and the opening angle inside the window
// searched (a correction of the curvature, not another pose). The
// decision and its figures stay `reg`'s; the pose, focal length,
// intrinsics (cx) and centre ray are the refit's. `reg` itself when there
// is nothing to search or nothing gained. Thread-safe.
Registration RefinePrincipalColumn(const Skyline& skyline, const HorizonProfile& horizon, const Registration& reg,
                                   const RegistrationOptions& options);

// Whether `pose` lies inside the gate of options.prior (gate_sigmas of each
// angle given; the roll within max_abs_roll_deg when no roll is given): the
// hypotheses the search keeps.
bool WithinPrior(const RegistrationOptions& options, const CameraPose& pose);

// Signed pixel distance from the image point (x, y) to the horizon projected
// with `pose` and `intrinsics`, measured across the projected silhouette:
// positive when the point lies below it (in the terrain). For diagnostics
// and tests.
double HorizonDistancePx(const HorizonProfile& horizon, const CameraPose& pose, const CameraIntrinsics& intrinsics,
                         double x, double y);

// Per image column, the y where the projected DEM horizon crosses the
// column's centre (bisection on the pixel ray's elevation against the
// horizon's at the ray's azimuth, to 1e-6 px); NaN when the column does not
// cross it within [-2 H, 3 H]. What a perfect skyline extractor would find
// for this pose. Thread-safe.
std::vector<double> ProjectedHorizonRows(const HorizonProfile& horizon, const CameraPose& pose,
                                         const CameraIntrinsics& intrinsics);

}  // namespace horizonreg
