// SPDX-License-Identifier: MIT
#include "pipeline/register_photo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <opencv2/core.hpp>
#include <sstream>

#include "match/predicted.h"
#include "skyline/band.h"
#include "skyline/refine.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

namespace {

// The prior 1-sigma of a pose given as initial, degrees (a search
// constrained to about +-3 sigma around it).
constexpr double kInitialSigmaDeg = 2.0;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The gate of a pose given as initial, as the refusals name it (the
// opening angle: its window's half-width and the slack an answer keeps to).
std::string PoseGateText(const RegistrationOptions& constrained) {
  const double hfov_share =
      std::sqrt(constrained.max_hfov_deg / constrained.min_hfov_deg) * (1.0 + RegistrationOptions::kKnownHfovSlack);
  return std::to_string(std::lround(constrained.prior.gate_sigmas * constrained.prior.compass_sigma_deg)) +
         " deg, the opening angle " + std::to_string(std::lround(100.0 * (hfov_share - 1.0))) + "%";
}

}  // namespace

PhotoPosition ResolvePhotoPosition(std::optional<double> lat, std::optional<double> lon, std::optional<double> agl,
                                   std::optional<double> alt, const SensorReading& sensors, const SensorReading& exif,
                                   const std::string& image) {
  if (lat.has_value() != lon.has_value()) throw InvalidArgument("latitude and longitude go together");
  PhotoPosition p;
  if (lat) {
    p.lat_deg = *lat, p.lon_deg = *lon, p.source = "arguments";
  } else if (sensors.lat_deg && sensors.lon_deg) {
    p.lat_deg = *sensors.lat_deg, p.lon_deg = *sensors.lon_deg, p.source = "sensors";
  } else if (exif.lat_deg && exif.lon_deg) {
    p.lat_deg = *exif.lat_deg, p.lon_deg = *exif.lon_deg, p.source = "exif";
  } else {
    throw InvalidArgument("no camera position for '" + image + "': give --lat and --lon (the photo has no GPS EXIF)");
  }
  if (!(std::abs(p.lat_deg) <= 90.0) || !(std::abs(p.lon_deg) <= 360.0))
    throw InvalidArgument("invalid camera position for '" + image + "': latitude within [-90, 90], longitude [-180, 360]");
  p.agl_m = agl, p.alt_m = alt;
  if (!agl && !alt && sensors.agl_m) p.agl_m = sensors.agl_m;
  if (!agl && !alt && !p.agl_m && p.source == "exif" && exif.alt_m) p.alt_m = exif.alt_m;
  return p;
}

InitialPose ParseInitialPose(const std::string& text, const std::string& what) {
  double v[4];
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &v[3], &tail) != 4 ||
      !(v[3] > 0 && v[3] < 170) || !(std::abs(v[1]) <= 90) || !(std::abs(v[2]) <= 90) || !std::isfinite(v[0]))
    throw InvalidArgument(what + " '" + text + "': expected AZ,PITCH,ROLL,HFOV in degrees");
  return {v[0], v[1], v[2], v[3]};
}

std::pair<double, double> ParseHfovRange(const std::string& s, const std::string& what) {
  const auto colon = s.find(':');
  double lo = NAN, hi = NAN;
  try {
    if (colon == std::string::npos) throw std::invalid_argument("no colon");
    size_t used = 0;
    lo = std::stod(s.substr(0, colon), &used);
    if (used != colon) throw std::invalid_argument("trailing");
    const std::string rest = s.substr(colon + 1);
    hi = std::stod(rest, &used);
    if (used != rest.size()) throw std::invalid_argument("trailing");
  } catch (const std::exception&) {
    throw InvalidArgument(what + " '" + s + "': expected MIN:MAX in degrees, e.g. 30:60");
  }
  if (!(lo > 0 && hi >= lo && hi < 170)) throw InvalidArgument(what + " '" + s + "': need 0 < MIN <= MAX < 170");
  return {lo, hi};
}

void PhotoOptions::Check() const {
  if (hfov_deg && !(*hfov_deg > 0 && *hfov_deg < 170)) ThrowField("hfov_deg", *hfov_deg, "in (0, 170) degrees");
  if (hfov_deg && hfov_range_deg) throw InvalidArgument("give a known opening angle or a range to search, not both");
  if (hfov_range_deg && !(hfov_range_deg->first > 0 && hfov_range_deg->second >= hfov_range_deg->first &&
                          hfov_range_deg->second < 170))
    throw InvalidArgument("hfov_range_deg: need 0 < MIN <= MAX < 170");
  if (position_sigma_m && !(*position_sigma_m >= 0 && *position_sigma_m <= 100'000))
    ThrowField("position_sigma_m", *position_sigma_m, "in [0, 100000] metres");
  if (refine_position && position_sigma_m && !(*position_sigma_m > 0.0))
    ThrowField("position_sigma_m", *position_sigma_m, "> 0 with refine_position");
  if (refine_position) refine_position->Check();
  if (check_position) check_position->Check();
  registration.Check();
}

SkylineOptions PhotoSkylineOptions(const PhotoOptions& options) {
  SkylineOptions so;
  if (options.sensors.roll_deg) so.roll_hint_deg = std::clamp(*options.sensors.roll_deg, -45.0, 45.0);
  so.Check();
  return so;
}

namespace {

// The frame the photo's EXIF focal length refers to (sensors.h FrameOf).
Frame35mm PhotoFrame(const PhotoOptions& po, int width, int height) {
  return FrameOf(width, height, po.exif.recorded_width_px, po.exif.recorded_height_px, po.exif.turned);
}

}  // namespace

std::string PhotoHfovWindow(const PhotoOptions& po, int width, int height, double& min_deg, double& max_deg) {
  if (po.hfov_deg) {
    min_deg = *po.hfov_deg * 0.97, max_deg = std::min(169.0, *po.hfov_deg * 1.03);
    return "--hfov";
  }
  if (po.hfov_range_deg) {
    std::tie(min_deg, max_deg) = *po.hfov_range_deg;
    return "--hfov-range";
  }
  if (const std::optional<double> h = PhotoExifHfovDeg(po, width, height)) {
    min_deg = std::max(1.0, *h * 0.9), max_deg = std::min(169.0, *h * 1.1);
    return std::string(po.exif.focal_35mm_from_crop_factor ? "exif-crop-factor" : "exif") +
           (PhotoFrame(po, width, height).cropped ? "-cropped" : "");
  }
  return "default";
}

std::optional<double> PhotoExifHfovDeg(const PhotoOptions& po, int width, int height) {
  if (po.hfov_deg || po.hfov_range_deg || !po.exif.focal_35mm) return std::nullopt;
  return HfovFromFocal35mm(*po.exif.focal_35mm, width, PhotoFrame(po, width, height));
}

double LensDepartureFromExif(const PhotoOptions& po, const Registration& r, int width, int height) {
  if (po.camera || !(r.focal_px > 0.0)) return 0.0;
  const std::optional<double> exif = PhotoExifHfovDeg(po, width, height);
  return exif ? std::abs(HfovFromFocalDeg(r.focal_px, width) / *exif - 1.0) : 0.0;
}

RegistrationOptions PhotoRegistrationOptions(const Site& site, const PhotoOptions& po, int width, int height,
                                             std::string* fov_source) {
  return PhotoRegistrationOptions(site.options().alt_m.has_value(), po, width, height, fov_source);
}

RegistrationOptions PhotoRegistrationOptions(bool altitude_given, const PhotoOptions& po, int width, int height,
                                             std::string* fov_source) {
  po.Check();
  RegistrationOptions ro = po.registration;
  const std::string fov = PhotoHfovWindow(po, width, height, ro.min_hfov_deg, ro.max_hfov_deg);
  ro.estimate_distortion = !po.pinhole;
  if (po.camera) ro.known_intrinsics = po.camera->Resized(width, height);
  // A photo cropped after it was taken: its camera's centre lies anywhere
  // over the width cut off (RefinePrincipalColumn searches it).
  if (const Frame35mm frame = PhotoFrame(po, width, height); frame.cropped && !po.camera)
    ro.principal_point_range = std::clamp((frame.width - width) / (2.0 * width), 0.0, 0.5);
  // How far the observer's given position may be off (the DEM error model):
  // coordinates given (arguments, a manifest row) are taken as surveyed
  // (1 m), a GPS fix from sensors or EXIF as a phone's (10 m); an altitude as
  // given (1 m, EXIF 20 m), a height above the DEM as that DEM's error under
  // the observer (2 m).
  const bool surveyed = po.position_source == "arguments";
  ro.dem_error.position_sigma_m = po.position_sigma_m.value_or(surveyed ? 1.0 : 10.0);
  ro.dem_error.height_sigma_m = altitude_given ? (po.position_source == "exif" ? 20.0 : 1.0) : 2.0;
  ro.prior.compass_deg = po.sensors.compass_deg ? po.sensors.compass_deg : po.exif.compass_deg;
  if (!po.sensors.compass_deg && po.exif.compass_deg) ro.prior.compass_sigma_deg = 20.0;
  ro.prior.pitch_deg = po.sensors.pitch_deg;
  ro.prior.roll_deg = po.sensors.roll_deg;
  ro.Check();
  if (fov_source) *fov_source = fov;
  return ro;
}

std::string UnknownFovHint(const Registration& r, const std::string& fov_source, int width) {
  if (r.registered || fov_source != "default" || !r.rival || !(r.focal_px > 0.0) || !(r.rival->focal_px > 0.0) ||
      width <= 0)
    return "";
  const double best = HfovFromFocalDeg(r.focal_px, width), rival = HfovFromFocalDeg(r.rival->focal_px, width);
  if (!(std::max(best, rival) > 1.2 * std::min(best, rival))) return "";
  std::ostringstream m;
  m << std::fixed << std::setprecision(0) << "; the opening angle is unknown (no EXIF focal length): the best pose"
    << " sees " << best << " deg, its rival " << rival << " deg; --hfov (or a narrow --hfov-range) rules one out";
  return m.str();
}

namespace {

// Searches again without the rivals ruled out, at most (each may bring
// up others among the candidates it refines next).
constexpr int kRidgeRounds = 4;

// Whether `r` was refused only for a rival: every gate that reads the best
// pose alone passes (it tells the pose, fits, its residual), and one that
// reads its rival fails (ambiguity, misfit ratio, evidence).
bool RefusedForARival(const Registration& r, const RegistrationOptions& o, int width) {
  if (r.registered || !(r.focal_px > 0.0) || !r.rival || !o.TellsThePose(r.informative_columns, width) ||
      !o.FitsEnough(r.inlier_fraction, r.unhidden_inlier_fraction) ||
      !(r.model_rms_px <= o.max_rms_px * ToleranceScale(width)))
    return false;
  return r.ambiguity_ratio < o.min_ambiguity_ratio || r.second_misfit < o.min_misfit_ratio * r.misfit ||
         r.evidence_nats < o.min_evidence_nats;
}

}  // namespace

Registration RegisterImageWithRidges(const Site& site, const cv::Mat& image, const Skyline& skyline,
                                     const RegistrationOptions& options, std::optional<RidgeCheck>* check) {
  const HorizonProfile& horizon = site.horizon();
  Registration r = RegisterImage(image, skyline, horizon, options);
  if (!RefusedForARival(r, options, skyline.width)) return r;
  const PhotoEdges edges = ComputePhotoEdges(image);
  RegistrationOptions without = options;
  RidgeCheck all;  // every rival checked, over the rounds
  // Each search without the rivals ruled out may find others among the
  // candidates it refines next: checked in turn, a few rounds at most.
  for (int round = 0; round < kRidgeRounds && RefusedForARival(r, without, skyline.width); ++round) {
    const RidgeCheck rc = CheckRidges(edges, horizon, site.ridges(), r, without);
    if (round == 0) all.best = rc.best;
    all.rivals.insert(all.rivals.end(), rc.rivals.begin(), rc.rivals.end());
    const std::vector<CameraPose> out = rc.RuledOut();
    if (out.empty()) break;
    without.ruled_out_rivals.insert(without.ruled_out_rivals.end(), out.begin(), out.end());
    r = RegisterImage(image, skyline, horizon, without);
  }
  if (check) *check = all;
  double most = 0.0;  // the largest share among the rivals ruled out
  int ruled_out = 0;
  for (const RidgeCheck::Rival& v : all.rivals)
    if (v.ruled_out) most = std::max(most, v.support.Share()), ++ruled_out;
  if (ruled_out == 0) return r;
  std::ostringstream m;
  m << std::fixed << std::setprecision(0) << " (" << ruled_out << (ruled_out == 1 ? " alternative" : " alternatives")
    << " ruled out by the inner ridges: " << 100.0 * all.best.Share()
    << "% of the best pose's ridge points on photo edges, at most " << 100.0 * most << "% of theirs)";
  r.message += m.str();
  return r;
}

PhotoRegistration RegisterPhoto(const Site& site, const cv::Mat& image_in, const PhotoOptions& po, ThreadPool* pool) {
  const cv::Mat image = AsBgr(image_in);
  if (image.type() != CV_8UC3 || image.cols < 8 || image.rows < 8)
    throw InvalidArgument("RegisterPhoto: the image must be 8-bit grey or BGR, at least 8 x 8 pixels");
  PhotoRegistration out;
  out.width = image.cols, out.height = image.rows;
  RegistrationOptions ro = PhotoRegistrationOptions(site, po, image.cols, image.rows, &out.fov_source);
  ro.pool = pool;
  out.options = ro;
  auto t0 = std::chrono::steady_clock::now();
  if (po.skyline) {
    if (po.skyline->width != image.cols || po.skyline->height != image.rows)
      throw InvalidArgument("RegisterPhoto: the given skyline is not for a " + std::to_string(image.cols) + " x " +
                            std::to_string(image.rows) + " image");
    out.skyline = *po.skyline;
  } else {
    out.skyline = ExtractSkyline(image, PhotoSkylineOptions(po));
    out.skyline_ms = MsSince(t0);
  }
  t0 = std::chrono::steady_clock::now();
  const HorizonProfile& horizon = site.horizon();
  Registration& r = out.registration;
  if (!po.initial) {
    // With a second look at a near miss, and the inner ridges' check of a rival.
    r = RegisterImageWithRidges(site, image, out.skyline, ro, &out.ridge_check);
  } else {
    // A known approximate pose (a fixed camera, a pose a few degrees off):
    // priors of a few degrees, the opening angle within 5% unless given.
    const CameraPose start{WrapAzimuthDeg(po.initial->azimuth_deg), po.initial->pitch_deg, po.initial->roll_deg};
    RegistrationOptions constrained = ro;
    constrained.prior.compass_deg = start.azimuth_deg;
    constrained.prior.pitch_deg = start.pitch_deg;
    constrained.prior.roll_deg = start.roll_deg;
    constrained.prior.compass_sigma_deg = kInitialSigmaDeg;
    constrained.prior.inclinometer_sigma_deg = kInitialSigmaDeg;
    const bool hfov_given = po.hfov_deg.has_value() || po.hfov_range_deg.has_value();
    if (!hfov_given)
      constrained.min_hfov_deg = po.initial->hfov_deg * 0.95,
      constrained.max_hfov_deg = std::min(169.0, po.initial->hfov_deg * 1.05);
    if (po.check_position) {
      // The pose given cannot vouch for the position: so close to it the
      // search has almost no rival, and the ambiguity test that refuses a
      // wrong position's or DEM's pose goes blind (searched near the pose
      // given, 2 of 91 wrong probes and 4 of 468 ring probes of the real
      // photos registered 1.3-32 deg off; searched over the whole horizon,
      // none). Unless the position is trusted, the search with no prior
      // decides and the pose given only vetoes (ConfirmedWithoutPrior).
      RegistrationOptions free = ro;
      free.prior = SensorPrior{};
      r = ConfirmedWithoutPrior(RegisterImageWithRidges(site, image, out.skyline, free, &out.ridge_check), constrained);
    } else {
      // A surveyed position (--trust-position): the search constrained to
      // the pose given, else, when that search fitted no pose, the graduated
      // local fit from it, which starts at a noise scale of 50 px per 1000
      // (about 2.5 deg at a 50-deg opening angle). The local fit only where
      // the search fitted no pose: where it did and refused it (a rival
      // nearby, too large a residual), a fit from the start would walk into
      // that rival's basin and, judged alone, pass.
      r = RegisterImageWithRidges(site, image, out.skyline, constrained, &out.ridge_check);
      if (!r.registered && !(r.focal_px > 0.0)) {
        r = RefinePose(out.skyline, horizon, start, FocalFromHfovPx(po.initial->hfov_deg, image.cols), hfov_given, ro,
                       50.0);
        // ... which must end inside the gate searched (from the Rainier DEM
        // it walked 32 deg and passed).
        if (r.registered && !WithinPose(constrained, r)) {
          r.registered = false;
          r.message = "the local fit from --initial ended outside the pose given (" + PoseGateText(constrained) +
                      "): another horizon fits, not the one expected";
        }
      }
    }
  }
  r.message += UnknownFovHint(r, out.fov_source, image.cols);
  if (po.refine_position) RefinePhotoPosition(site, image, *po.refine_position, ro, out, pool);
  // A cropped photo's centre before the position check: the check reads
  // the lens the answer will report (the centre trades against the focal
  // length, PositionCheckOptions::lens_departure).
  if (r.registered && ro.principal_point_range > 0.0) r = RefinePrincipalColumn(out.skyline, out.Horizon(site), r, ro);
  if (po.check_position && r.registered) {
    PositionCheckOptions co = *po.check_position;
    co.ridges_decided = out.ridge_check && !out.ridge_check->RuledOut().empty();
    co.lens_departure = LensDepartureFromExif(po, r, image.cols, image.rows);
    out.position_check = CheckPositionConsistency(site, out.Horizon(site), out.skyline, r, ro, co, pool);
    if (!out.position_check->consistent) {
      r.registered = false;
      r.message = out.position_check->message;
    }
  }
  out.match_ms = MsSince(t0);
  return out;
}

Skyline RegisteredSkyline(const Site& site, const cv::Mat& image_in, const PhotoRegistration& photo) {
  const Registration& r = photo.registration;
  const cv::Mat image = AsBgr(image_in);
  if (!r.registered || image.cols != photo.skyline.width || image.rows != photo.skyline.height) return photo.skyline;
  const SkylineWindow win = ExpectedSkylineWindow(photo.Horizon(site), r, photo.options, image.cols, image.rows);
  return GuideSkyline(image, photo.skyline, win.predicted, win.above_px, win.below_px);
}

void RefinePhotoPosition(const Site& site, const cv::Mat& image, const PositionOptions& position_options,
                         const RegistrationOptions& ro, PhotoRegistration& out, ThreadPool* pool) {
  const auto t0 = std::chrono::steady_clock::now();
  const Registration first = out.registration;
  // An eye given below the terrain (an EXIF altitude tens of metres low)
  // sees nothing useful: the search starts above the ground there.
  const Eigen::Vector3d start = PositionSearchStart(site);
  PositionEstimate est;
  if (start != Eigen::Vector3d::Zero()) {
    HorizonOptions ho = site.horizon_options();
    ho.pool = pool;
    const HorizonProfile start_horizon =
        ComputeHorizonNear(site.window(), LocalFrame(site.observer()).GeodeticFromEnu(start), ho, site.horizon());
    const Registration lifted = RegisterImage(image, out.skyline, start_horizon, ro);
    est = RefinePosition(site, out.skyline, lifted, ro, position_options, pool, start, &start_horizon);
    if (est.offset_enu_m == Eigen::Vector3d::Zero()) {
      // Not observable: still not below the ground.
      est.offset_enu_m = start;
      est.observer = LocalFrame(est.given).GeodeticFromEnu(start);
      est.horizon = start_horizon;
      est.message += "; the eye given below the terrain is put 1.7 m above it";
    }
  } else {
    est = RefinePosition(site, out.skyline, first, ro, position_options, pool);
  }
  auto keep_given = [&](const std::string& why) {
    PositionEstimate kept;
    kept.given = kept.observer = est.given;
    kept.prior_sigma_enu_m = kept.sigma_enu_m = est.prior_sigma_enu_m;
    kept.horizons = est.horizons;
    kept.horizon = site.horizon();
    kept.message = why;
    est = std::move(kept);
  };
  if (est.offset_enu_m != Eigen::Vector3d::Zero() || est.observable_axis[0] || est.observable_axis[1] ||
      est.observable_axis[2]) {
    // Registered again at the estimate, by the whole decision (search,
    // ambiguity, evidence) under the same DEM error model as at the given
    // position (the prior of the refinement does not widen the gates: from
    // a position kilometres off, a tolerance of tens of metres at near
    // terrain lets wrong poses through): a position refinement never lets
    // a pose through that the gates would refuse there.
    Registration again = RegisterImage(image, out.skyline, est.horizon, ro);
    if (again.registered) {
      out.registration = std::move(again);
    } else if (first.registered) {
      keep_given("the registration at the refined position failed (" + again.message +
                 "): the given position is kept");
    } else {
      keep_given("not registered at the refined position either (" + again.message +
                 "): the given position is kept");
    }
  }
  out.position = std::move(est);
  out.position_ms = MsSince(t0);
}

bool WithinPose(const RegistrationOptions& constrained, const Registration& r) {
  if (!WithinPrior(constrained, r.pose)) return false;
  return r.focal_px > 0.0 && constrained.AdmitsHfov(r.hfov_deg) && constrained.KeepsKnownHfov(r.hfov_deg);
}

Registration ConfirmedWithoutPrior(Registration alone, const RegistrationOptions& constrained) {
  if (!alone.registered) {
    alone.message += " (searched with no prior: the pose given cannot vouch for the position; --trust-position "
                     "lets it decide)";
  } else if (!WithinPose(constrained, alone)) {
    alone.registered = false;
    alone.message = "the skyline registers outside the pose given by --initial (" + PoseGateText(constrained) +
                    "): another horizon, or another position";
  } else {
    alone.message += " (the pose given confirmed)";
  }
  return alone;
}

Registration RegisterImage(const cv::Mat& image, const Skyline& skyline, const HorizonProfile& horizon,
                           const RegistrationOptions& options) {
  Registration r = Register(skyline, horizon, options);
  if (!r.registered)
    if (auto again = RecheckWithGuidedSkyline(image, skyline, horizon, r, options)) {
      if (again->registered) return *again;
      r.message = again->message;  // the first look's answer and why the second did not change it
    }
  return r;
}

namespace {

// The misfit of `reg`'s rival (the distinct alternative its ambiguity ratio
// is taken against), refined on the skyline re-read near the rival's own
// projection, over reg's misfit; infinity when there is none or nothing near
// it was re-read.
template <typename Reread>
double RivalAfterItsOwnReread(const Registration& reg, const Reread& reread_at, const HorizonProfile& horizon,
                              const RegistrationOptions& options, int w, int h) {
  if (!reg.rival) return INFINITY;
  CameraIntrinsics k = reg.Intrinsics(w, h);
  if (!options.known_intrinsics) k.focal_px = reg.rival->focal_px;
  const auto [guided, reread] = reread_at(reg.rival->pose, k);
  if (reread == 0) return INFINITY;
  const Registration alt = RefinePose(guided, horizon, reg.rival->pose, reg.rival->focal_px, false, options);
  return alt.misfit > 0.0 && reg.misfit > 0.0 ? alt.misfit / reg.misfit : INFINITY;
}

}  // namespace

std::optional<Registration> RecheckWithGuidedSkyline(const cv::Mat& image, const Skyline& skyline,
                                                     const HorizonProfile& horizon, const Registration& first,
                                                     const RegistrationOptions& options) {
  // A near miss, not a guess: at most 0.2 short of the inlier share needed.
  const double min_first_inliers = options.min_inlier_fraction - 0.2;
  constexpr double kMinStep = 15.0;  // BGR distance of the 3-row means across the step (sky noise ~3)
  // A faint miss: a first look short of that (0.2-0.3 short of the inlier
  // share, its ambiguity at least 0.8 of the gate) is looked at again
  // as a hazy photo's: the columns the extraction nulled are read too, and a
  // step needs 2.5 times the sky's own noise (the median over the columns of
  // the largest step in the 18 rows from 6 above the extracted boundary),
  // within 9-15. CG05_20050811_190000: its far range fades into haze 8-12
  // over a smooth sky (steps up to 3.1), its true pose fits 38% on the first
  // look (ambiguity 1.15), 67% (1.42) on the faint re-read; at 15 and without
  // the nulled columns 66 columns were re-read and it stayed unregistered, at
  // 9.5 it is refused too. For a near miss the faint look is not taken: the
  // nulled columns and fainter steps help the rival's re-read as much (the
  // EXIF-less copies of AK01b_20100525 and AK01b_20100602 were refused, the
  // rival within 8%), and from 2 km beside AKJNC_20120813 with --sensors the
  // rival's re-read fell behind a pose 2.7 deg off; a miss with 76% of its
  // skyline fitting but ambiguous at 0.8-0.85 of the gate is no hazy photo
  // (the centre half of AK01_20070922 from 2 km east registered 1.6 deg off
  // through the faint look). JPEG's blocks step 5-8 in a sky at quality 30,
  // so a fixed 9 read them.
  const double min_faint_inliers = options.min_inlier_fraction - 0.3;
  constexpr double kMinFaintStep = 9.0, kSkyNoiseFactor = 2.5;
  constexpr int kSkyRowsFrom = 6, kSkyRows = 18, kMinSkyRows = 12;
  constexpr double kMaxPoseMoveDeg = 0.2;
  // The best alternative re-read near its own projection, as the best pose
  // was: its misfit at least this much over the best's (from 2 km away the
  // re-read fits a wrong pose's rival within 3%; the true poses' rivals stay
  // about 20% or more worse).
  constexpr double kMinRivalMisfitRatio = 1.1;
  // The columns to re-read inflate the best pose's cost, so its ambiguity
  // ratio reads low; the search on the re-read skyline checks it again.
  const double min_first_ambiguity = 0.85 * options.min_ambiguity_ratio, min_faint_ambiguity = 0.8 * options.min_ambiguity_ratio;
  // ... and its residual, which the same columns inflate, at most 20% over
  // the gate.
  const double max_first_rms = 1.2 * options.max_rms_px;
  const int w = skyline.width, h = skyline.height;
  const double px_scale = ToleranceScale(w), tau = options.inlier_px * px_scale;
  // Not under a strip cut from the top (a webcam's timestamp): the re-read
  // fits the sky above the skyline, and the strip has cut it to a few rows
  // (the real photos under a strip: the second look registered
  // AK01b_20100525 from 2 km away 4.6 deg off, 1 of 91 wrong probes and 1
  // of 468 ring probes; without it 7 of 13 register, none falsely).
  if (first.registered || skyline.overlay_top_rows > 0 || !(first.focal_px > 0.0) ||
      first.inlier_fraction < min_faint_inliers || !(first.model_rms_px <= max_first_rms * px_scale))
    return std::nullopt;
  const bool faint = first.inlier_fraction < min_first_inliers;
  if (first.ambiguity_ratio < (faint ? min_faint_ambiguity : min_first_ambiguity)) return std::nullopt;
  const cv::Mat bgr = AsBgr(image);
  if (bgr.type() != CV_8UC3 || bgr.cols != w || bgr.rows != h || static_cast<int>(skyline.y.size()) != w)
    return std::nullopt;
  auto mean3 = [&](int r0, int c) {  // mean BGR of rows r0 .. r0 + 2
    cv::Vec3d m(0, 0, 0);
    for (int r = r0; r < r0 + 3; ++r) m += cv::Vec3d(bgr.at<cv::Vec3b>(r, c));
    return m / 3.0;
  };
  double min_step = kMinStep;
  if (faint) {
    std::vector<double> largest;  // per column (every other one) with enough sky rows above its boundary
    for (int c = 0; c < w; c += 2) {
      const double y = skyline.MatchY(c);
      if (!std::isfinite(y)) continue;
      const int below = static_cast<int>(std::floor(y)) - kSkyRowsFrom;
      double step = 0.0;
      int rows = 0;
      for (int r = std::max(3, below - kSkyRows); r < below && r + 2 < h; ++r, ++rows)
        step = std::max(step, cv::norm(mean3(r, c) - mean3(r - 3, c)));
      if (rows >= kMinSkyRows) largest.push_back(step);
    }
    if (largest.size() >= 16)
      min_step = std::clamp(kSkyNoiseFactor * skyline_detail::Quantile(largest, 0.5), kMinFaintStep, kMinStep);
  }
  // Whether the rows above a step at row r of column c are sky: the 3 rows
  // from `gap` rows above it continue the 3 above those. Read next to the
  // step (gap 3) or, on a soft real edge whose transition still fills those
  // rows (a hazy snow ridge fades from sky to snow over 4-6 rows), further
  // up (gap 6): AKJNC_20120813 has 184 columns re-read instead of 75, and
  // re-encoded (JPEG quality 95), grey or EXIF-less copies of the real
  // photos register 25 of 39 instead of 21.
  auto sky_above = [&](int r, int gap, int c) {
    return r - gap - 3 >= 0 && cv::norm(mean3(r - gap, c) - mean3(r - gap - 3, c)) <= 0.5 * min_step;
  };
  std::vector<double> scores;
  // The skyline re-read near the horizon projected at `pose`, and how many
  // columns were re-read.
  auto reread_at = [&](const CameraPose& pose, const CameraIntrinsics& k) {
    const std::vector<double> pred = PredictedSkyline(horizon, pose, k);
    std::pair<Skyline, int> out{skyline, 0};
    for (int c = 0; c < w; ++c) {
      // A column with no boundary: in a faint look read down to the bottom
      // of the window (a faint ridge the extraction nulled), else hidden.
      const double p = pred[c], y = std::isfinite(skyline.MatchY(c)) || !faint ? skyline.MatchY(c) : h;
      if (!std::isfinite(p) || !std::isfinite(y) || y - p <= tau) continue;  // fits, lies above, or is hidden
      // Boundaries between rows r - 1 and r, above the extracted one.
      // (Never within a strip along the bottom: under one along the top
      // there is no second look.)
      const int lo = std::max(6, static_cast<int>(std::floor(p - 2 * tau)));
      const int hi = std::min({h - 3 - skyline.overlay_bottom_rows, static_cast<int>(std::ceil(p + 2 * tau)),
                               static_cast<int>(std::floor(y - tau))});
      if (hi < lo) continue;
      const auto [r, yr, contrast] = StrongestStep(
          lo, hi, [&](int row) { return cv::norm(mean3(row, c) - mean3(row - 3, c)); }, scores);
      if (contrast < min_step || !(sky_above(r, 3, c) || sky_above(r, 6, c))) continue;
      out.first.y[c] = yr;
      if (c < static_cast<int>(out.first.y_alt.size())) out.first.y_alt[c] = NAN;  // re-read: one candidate
      out.first.confidence[c] = std::min(1.0, contrast / (4.0 * min_step));
      ++out.second;
    }
    return out;
  };
  const auto [guided, reread] = reread_at(first.pose, first.Intrinsics(w, h));
  // A few columns would only give the refit a second chance at the same
  // skyline: the re-read must be a part of it that can carry the decision.
  if (reread < std::max(8, w / 32)) return std::nullopt;
  Registration r = RefinePose(guided, horizon, first.pose, first.focal_px, false, options);
  auto moved = [&](const CameraPose& p) {
    return std::abs(AngDiffDeg(p.azimuth_deg, first.pose.azimuth_deg)) > kMaxPoseMoveDeg ||
           std::abs(p.pitch_deg - first.pose.pitch_deg) > kMaxPoseMoveDeg;
  };
  std::ostringstream m;
  if (r.registered && moved(r.pose)) {
    r.registered = false;
    m << "the re-read skyline moved the pose";
  } else if (r.registered) {
    // The re-read skyline must register on its own, by the whole decision
    // (ambiguity and evidence included), at the same pose.
    // ... with no sensor prior: a re-read near the pose found helps that
    // pose wherever the camera stands, and the compass's gate would hide the
    // rivals that refuse it from a wrong position (from 2 km beside
    // AKJNC_20120813, sensors 2 deg off, 3 of 36 ring probes registered 3-5
    // deg off; searched over the whole horizon, none). As with --initial,
    // the priors cannot vouch for the position.
    RegistrationOptions free = options;
    free.prior = SensorPrior{};
    const Registration search = Register(guided, horizon, free);
    if (!search.registered) {
      r.registered = false;
      m << "the re-read skyline does not register on its own (" << search.message << ")";
    } else if (moved(search.pose)) {
      r.registered = false;
      m << "the re-read skyline registers elsewhere";
    } else if (const double rival = RivalAfterItsOwnReread(search, reread_at, horizon, free, w, h);
               rival < kMinRivalMisfitRatio) {
      // Re-reading near a pose's own projection helps any pose; the best
      // alternative given the same help must still fit clearly worse.
      r.registered = false;
      m << "ambiguous once the best alternative's skyline is re-read too (misfit ratio " << std::setprecision(3)
        << rival << ")";
    } else {
      r = search;
      m << "registered (" << reread << " columns re-read near the DEM horizon)";
    }
  } else {
    m << r.message;
  }
  // Refused: the first look's answer leads, then why the second did not
  // change it.
  if (!r.registered)
    m.str(first.message + "; a second look, " + std::to_string(reread) + " columns re-read near the DEM horizon: " +
          m.str());
  r.message = m.str();
  return r;
}

}  // namespace horizonreg
