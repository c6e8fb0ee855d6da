// SPDX-License-Identifier: MIT
// Position consistency (issues 13 and 15): is the given camera position the
// one the skyline was seen from? From 2-5 km beside the true position, a
// skyline of ranges 15-30 km away can still be fitted: the parallax between
// nearer and farther peaks becomes a near-linear stretch that the opening
// angle, pitch and roll absorb, with as many inliers as at the truth. Only
// the cost tells them apart, and it falls towards the true position in a
// bowl (measured on the real photos: from a wrong position 2-5 km off, the
// cost at the truth is 12-34% lower; from the truth, no position within
// 4 km fits better). The bowl is about 1 km across on a 100 m DEM, and a
// wrong position can sit in a shallow one of its own (cost maps of the real
// photos on a 500 m grid). So the check searches the horizontal position
// around the given one (a pattern search over exact horizons of the view's
// sector, the skyline searched again at each place as the photo was; a
// grid out to 4 km where the given position is no clear bowl bottom) and
// refuses a registration that fits clearly better somewhere else.
#pragma once

#include <Eigen/Core>
#include <string>

#include "match/register.h"
#include "pipeline/site.h"
#include "skyline/skyline.h"
#include "util/thread_pool.h"

namespace horizonreg {

struct PositionCheckOptions {
  double first_step_m = 1000.0;   // the pattern's first step ...
  double far_ring_m = 3000.0;     // ... and a ring this far out, when the cost falls on the first (a farther bowl)
  double min_step_m = 500.0;      // halved down to this (only once the search has moved)
  int directions = 8;             // places per ring
  double max_offset_m = 6000.0;   // the search stays within this of the given position
  int max_horizons = 48;          // and visits at most this many places (each fitted once: horizons <= this)
  int candidates = 4;             // each place's search: distinct hypotheses kept (at most the registration's) ...
  int refined_candidates = 2;     // ... of which this many get the least squares
  // Refused when some place at least min_offset_m away fits with a cost
  // below this share of the given position's. Measured: the 12 real photos
  // registered at their true positions, no place of the first rings fits
  // better (ratio 1.0); the 23 rendered scenes registered, >= 0.965 but
  // rainier_00 (0.907, 1 km off); the 11 false registrations of real photos
  // from 2-5 km away, <= 0.884 (the search stops below the limit; their
  // bowls reach 0.68-0.88).
  double max_cost_ratio = 0.90;
  double min_offset_m = 500.0;
  // A registration whose rivals only the inner ridges ruled out
  // (pipeline/ridge_check.h; RegisterPhoto sets it): a pose the skyline
  // alone left ambiguous must sit at the bottom of its bowl. Refused from a
  // cost ratio of max_cost_ratio_ridges, and the wide look taken out to
  // wide_radius_ridges_m whatever wide_radius_m (which a station's vouch
  // sets to 0 in `batch`: its photos' answers stay those of the full check).
  // The ridges line up from a wrong position 2 km away as well: two ring
  // probes of the real photos registered 1.2 and 1.6 deg off so under the
  // plain limit, their best places at 0.907 and 0.945.
  bool ridges_decided = false;
  double max_cost_ratio_ridges = 0.97;
  double wide_radius_ridges_m = 4000.0;
  // A registration whose opening angle departs from the one its EXIF focal
  // length gives (lens_departure: |fitted / EXIF - 1|, 0 without EXIF;
  // RegisterPhoto sets it) is held to a stricter limit, from max_cost_ratio
  // at lens_departure_from up to max_cost_ratio_ridges at
  // lens_departure_full and beyond (and the wide look out to
  // wide_radius_ridges_m): from a wrong position the search absorbs the
  // terrain's parallax into the focal length. Measured on the real photos
  // and their photometric copies at their true stations (94
  // registrations): 0.954-0.993 of the EXIF's opening angle (a departure of
  // at most 0.046); the 5 false registrations of the photometric copies'
  // rings (3744 probes 2-3 km away, 1.3-4.0 deg off, best places at cost
  // ratios 0.901-0.953): 0.883-0.935 or 1.068-1.124 (0.065-0.124). The
  // price: a 3/4 crop of AKJNC_20120813 at its station fits 0.94 (its
  // searched centre trades against the focal length) and a place 3.3 km
  // away 0.969 of its cost: refused.
  double lens_departure = 0.0;
  double lens_departure_from = 0.04;
  double lens_departure_full = 0.06;
  // The limit for this registration (the ridges' or the lens's).
  double MaxCostRatio() const;
  // The sector computed and searched: the view's opening angle and this
  // much each side (the view turns as the camera moves).
  double view_margin_deg = 15.0;
  // The wide look: when some place of the first ring fits within this share
  // of the given position's cost (or better) and nothing was refused, a
  // hexagonal grid of places this far apart out to this radius (0: none).
  double wide_trigger = 0.03;
  double wide_spacing_m = 600.0;
  double wide_radius_m = 4000.0;
  // ... and always, whatever the first ring, when the eye's altitude was not
  // given and the opening angle is as good as known
  // (RegistrationOptions::OpeningAngleKnown). Without an altitude the eye
  // stands on the DEM's ground at the given place, and a known opening
  // angle leaves no rival at another one, which is what refuses most wrong
  // positions: from a ring of places 2-5 km from the real photos' stations
  // (--agl 2 --hfov), 4 of 468 registered 2.8-165 deg off, 3 of them at the
  // bottom of a bowl of their own (first ring steeper than the trigger). The
  // look refuses 2 of the 4 and no true registration (the real photos so
  // given, the dev scenes with --hfov), for about 1 s more per photo.
  bool wide_when_unpinned = true;
  void Check() const;  // Throws InvalidArgument naming the field.
};

struct PositionCheck {
  bool consistent = true;
  double cost_ratio = 1.0;                        // best place's cost over the given position's
  Eigen::Vector2d best_offset_en_m{0.0, 0.0};     // where the best place is (east, north), metres
  int horizons = 0;                               // horizons computed
  int wide_places = 0;                            // places of the wide look's grid fitted (0: not needed)
  double ms = 0.0;
  std::string message;  // why it was refused, else empty
  // The orientation each place's search fits (the optical axis, at the
  // place's own best focal length): at the given position and at the best
  // place. Their difference is how far the orientation rests on the
  // position: at the real photos' true stations (their crops most) a place
  // 1-3 km away that fits 2-9% better (a cost ratio of 0.91-0.98, within
  // the limit) can carry a pose 0.2-2.4 deg away, and the skyline cannot
  // tell which place is right.
  CameraPose given_pose, best_pose;
  // Refused only under the stricter limit of a registration the inner
  // ridges decided (PositionCheckOptions::ridges_decided): no place fits
  // better than max_cost_ratio, so the pose is doubted, not the position.
  bool only_ridges_limit = false;
  // Refused only under the stricter limit of a lens that departs from its
  // EXIF (PositionCheckOptions::lens_departure): the position is doubted.
  bool only_lens_limit = false;
  double OffsetM() const { return best_offset_en_m.norm(); }
  double BearingDeg() const;  // of the best place from the given one, clockwise from north
  // best_pose - given_pose in azimuth (wrapped to +-180) and pitch, degrees;
  // 0 when the best place is the given position.
  double AzimuthShiftDeg() const;
  double PitchShiftDeg() const { return best_pose.pitch_deg - given_pose.pitch_deg; }
};

// Checks `reg` (registered at `horizon`, seen from `horizon.observer`) for
// position consistency. The eye at each place: at the given altitude but
// not below the ground there (+1.7 m) when an altitude was given, else at
// the given height above the ground. The horizons reach as far as the
// given one does in the view (+30%, +3 km), within the site's window. Runs
// on `pool` when given. Thread-safe.
PositionCheck CheckPositionConsistency(const Site& site, const HorizonProfile& horizon, const Skyline& skyline,
                                       const Registration& reg, const RegistrationOptions& options,
                                       const PositionCheckOptions& check_options, ThreadPool* pool);

}  // namespace horizonreg
