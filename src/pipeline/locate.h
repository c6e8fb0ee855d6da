// SPDX-License-Identifier: MIT
// Where a photo was taken, from its skyline alone (no GPS): the 360-degree
// horizons of candidate viewpoints inside a search area are compared with the
// photo's skyline, coarse to fine, and the photo is registered at the best.
//
//  1. Coarse: a grid over the area (spacing ~ radius / 30, 100-400 m), each
//     viewpoint's horizon at 1 deg on the DEM pooled to ~100 m posts (block
//     maxima: peaks survive) and out to 40 km, compared with the skyline as
//     an elevation profile for every azimuth and a few opening angles
//     (pitch and roll as nuisance offsets, truncated squared residuals).
//  2. Fine: around the best distinct coarse viewpoints, grids of half, then
//     a quarter, of the spacing on the full DEM at 0.25 deg.
//  3. Exact: `RegisterPhoto` at the best fine viewpoints (the full
//     registration, its gates included). The photo is located when the best
//     registers with a close fit (misfit <= 1) and enough evidence (350
//     nats: more than a given position needs), every other place tried that
//     can tell the pose (enough informative columns) fits clearly worse
//     (misfit ratio at least 1.5) and the viewpoints that fit
//     about as well (within 15%) agree on the orientation within 0.3 deg;
//     else no_match, with the runners-up listed.
#pragma once

#include <string>
#include <vector>

#include "pipeline/register_photo.h"
#include "pipeline/site.h"

namespace horizonreg {

struct LocateOptions {
  double lat_deg = NAN, lon_deg = NAN;  // centre of the search area
  double radius_m = 10'000.0;           // the camera stands within this distance of the centre
  double grid_m = 0.0;                  // coarse spacing; 0: radius / 30 within [100, 400] m
  double coarse_max_distance_m = 40'000.0;  // candidate horizons see this far (the final one: site.max_distance_m)
  // Candidate horizons on the DEM pooled to posts about this far apart. At
  // 200 m the pooled near terrain moved the best places: scored at the true
  // position, it ranked 152nd-2169th of 2821 places in four of the seven
  // missed dev scenes (zion_01, cascades_01, fuji_00, rainier_00); at 100 m
  // fuji_00 and zion_01 rank first there, and 2 more scenes are located,
  // for a coarse stage of 5-10 s instead of 3-7 s.
  double coarse_post_m = 100.0;
  int coarse_keep = 12;                 // distinct coarse viewpoints refined
  int register_keep = 12;               // fine viewpoints registered (those whose profile fits within 3x the best's polished)
  double min_distinctiveness = 1.5;     // every other place's registration misfit over the answer's, at least
  double max_misfit = 1.0;              // the answer's registration misfit (mean truncated chi^2), at most
  // The answer's registration evidence (Registration::evidence_nats), at
  // least: a searched position has had thousands of chances, and a plain
  // skyline fits some place far off closely (cascades_01, with the DEM
  // pooled to 100 m: 4.8 km and 4.6 deg off, misfit 0.29, no rival at that
  // place, 167 nats). The 11 dev scenes located right: 707-2456 nats.
  double min_evidence_nats = 350.0;
  double max_orientation_spread_deg = 0.3;  // viewpoints that fit equally well may disagree this much, no more
  SiteOptions site;                     // eye height (agl), refraction, horizon distance of the final registration
  PhotoOptions photo;                   // opening angle, EXIF, camera, as for `register`
  void Check() const;                   // Throws InvalidArgument naming the field.
};

struct LocateCandidate {
  double lat_deg = 0.0, lon_deg = 0.0;
  double cost = 0.0;             // mean truncated squared misfit of the profiles, deg^2 (fine stage)
  double coarse_cost = 0.0;      // the same at the coarse stage (every seed has one)
  double azimuth_deg = 0.0;      // the azimuth of the image centre that fitted best
  double hfov_deg = 0.0;         // the opening angle that fitted best
  bool registered = false;       // after the exact registration (when it was run)
  bool tried = false;            // the exact registration was run
  bool informative = false;      // its registration had enough informative columns to tell the pose
  double misfit = NAN;           // its misfit (lower is better)
  std::string message;           // its status message
  // Of the viewpoints registered around it, those that fit about as well:
  // their largest and RMS distance from it and their largest orientation difference.
  // Other places that register about as well count too.
  double position_spread_m = 0.0, position_rms_m = 0.0, orientation_spread_deg = 0.0;
  double registered_azimuth_deg = NAN, registered_pitch_deg = NAN;  // the pose its registration found
};

struct LocateResult {
  bool located = false;
  std::string message;
  std::vector<LocateCandidate> candidates;  // best first; [0] is the answer when located
  int coarse_viewpoints = 0, fine_viewpoints = 0;
  // The distinctiveness of the skyline in the area: the second-best distinct
  // coarse viewpoint's profile misfit over the best one's (inf when alone),
  // and the least registration misfit of the other places tried (more than
  // 3 grid steps away) over the answer's (inf when none): the latter decides.
  double distinctiveness = 0.0, registration_distinctiveness = 0.0;
  double grid_m = 0.0;
  // The answer's position check refused it for another place: what that
  // place gave when polished (registered there instead, or the answer
  // registered without the check), one line each.
  std::vector<std::string> followed_checks;
  double dem_ms = 0.0, skyline_ms = 0.0, coarse_ms = 0.0, fine_ms = 0.0, register_ms = 0.0;
  // The registration at the answer (or at the best tried viewpoint), and its site.
  std::unique_ptr<Site> site;
  PhotoRegistration registration;
};

// Locates an 8-bit BGR photo within the area. `dem` are the DEM files
// (a mosaic). Throws InvalidArgument / IoError for bad options or files
// (e.g. no DEM data in the area); a photo that cannot be located is a
// result with located == false.
LocateResult Locate(const std::vector<std::string>& dem, const cv::Mat& image, const LocateOptions& options,
                    ThreadPool* pool = nullptr);
// The same in a DEM window already read (it must reach radius_m plus
// site.max_distance_m around the area's centre for the full horizons).
LocateResult LocateInWindow(const TerrainWindow& window, const cv::Mat& image, const LocateOptions& options,
                            ThreadPool* pool = nullptr);

namespace locate_detail {
// A photo's skyline as an elevation profile, about `per_deg` samples per
// degree across the image: each sample's azimuth offset from the image
// centre and elevation, exact for a centred pinhole of opening angle
// hfov_deg pitched by pitch_deg with no roll (elevation NaN where the
// skyline is missing).
struct Profile {
  std::vector<double> offset_deg, elevation_deg;
  double hfov_deg = 0.0, pitch_deg = 0.0;
};
Profile SkylineProfile(const Skyline& skyline, double hfov_deg, double pitch_deg, double per_deg);
// The best azimuth of the image centre for `profile` against a 360-degree
// horizon (bins of horizon.azimuth_step_deg), searched every `step_deg`:
// the mean of min(r^2, 1 deg^2) over the profile's samples after removing a
// pitch offset and a roll slope. Returns {cost, azimuth}; cost is +inf when
// fewer than 60% of the samples have a skyline. With within_deg < 180, only
// azimuths within within_deg of around_deg are searched. A search of 64
// steps or more (and 32 samples or more) costs every step on every 4th
// sample first and the best eighth of them (at least 8) in full.
std::pair<double, double> MatchProfile(const Profile& profile, const std::vector<double>& horizon_elevation_deg,
                                       double horizon_step_deg, double step_deg, double around_deg = 0.0,
                                       double within_deg = 180.0);
// `window` with each grid pooled by whole factors to posts about post_m
// apart (the mean of each block, centred on the kept post); grids already
// that coarse are kept.
TerrainWindow Coarsen(const TerrainWindow& window, double post_m);
}  // namespace locate_detail

}  // namespace horizonreg
