// SPDX-License-Identifier: MIT
// Registering one photo at a Site: the position and its error model, the
// opening-angle window from the arguments, the EXIF or the default range,
// priors from sensors, a known camera or a lens to fit, a known approximate
// pose, the skyline, the search and the second look at a near miss. What
// `horizonreg register`, `batch`, `demo`, the tracker and Python call.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "camera/camera.h"
#include "match/register.h"
#include "pipeline/position.h"
#include "pipeline/position_check.h"
#include "pipeline/ridge_check.h"
#include "pipeline/site.h"
#include "sensors/sensors.h"
#include "skyline/skyline.h"
#include "util/thread_pool.h"

namespace cv {
class Mat;
}

namespace horizonreg {

// Where the camera stands: the given coordinates, else the sensor file's,
// else the photo's GPS EXIF. `source` is "arguments", "sensors" or "exif"
// (coordinates in a batch manifest count as arguments).
struct PhotoPosition {
  double lat_deg = NAN, lon_deg = NAN;
  std::optional<double> agl_m, alt_m;
  std::string source = "arguments";
};
// Throws InvalidArgument naming `image` when no position is known.
PhotoPosition ResolvePhotoPosition(std::optional<double> lat, std::optional<double> lon, std::optional<double> agl,
                                   std::optional<double> alt, const SensorReading& sensors, const SensorReading& exif,
                                   const std::string& image);

// A known approximate pose (a fixed camera): azimuth, pitch, roll, opening angle.
struct InitialPose {
  double azimuth_deg = 0.0, pitch_deg = 0.0, roll_deg = 0.0, hfov_deg = 0.0;
};
// "AZ,PITCH,ROLL,HFOV" in degrees; throws InvalidArgument naming `what` and the text.
InitialPose ParseInitialPose(const std::string& text, const std::string& what = "--initial");
// "MIN:MAX" opening angles in degrees; throws InvalidArgument naming `what` and the text.
std::pair<double, double> ParseHfovRange(const std::string& text, const std::string& what = "--hfov-range");

struct PhotoOptions {
  SensorReading sensors;  // compass / inclinometer priors (a --sensors file or a manifest's)
  SensorReading exif;     // the photo's EXIF (35 mm focal length, GPS direction), empty to ignore it
  std::optional<double> hfov_deg;                          // known opening angle (searched within +-3%)
  std::optional<std::pair<double, double>> hfov_range_deg;  // else this range, else EXIF +-10%, else the default
  std::optional<CameraIntrinsics> camera;                   // known intrinsics, used exactly
  std::optional<InitialPose> initial;                       // refine from here instead of searching
  std::optional<Skyline> skyline;                           // use this skyline instead of extracting one
  bool pinhole = false;                                     // no lens distortion: do not fit k1
  std::string position_source = "arguments";               // PhotoPosition::source
  std::optional<double> position_sigma_m;  // how far the position may be off (default by its source)
  // Refine the position too (pipeline/position.h), within this prior
  // (DefaultPositionOptions); the registration is then made at the estimate.
  std::optional<PositionOptions> refine_position;
  // Refuse a registration that fits clearly better from somewhere else
  // (pipeline/position_check.h); nullopt to trust the position blindly.
  std::optional<PositionCheckOptions> check_position = PositionCheckOptions{};
  RegistrationOptions registration;        // thresholds; priors, opening angles and intrinsics are set from the above
  void Check() const;                      // Throws InvalidArgument naming the field.
};

struct PhotoRegistration {
  Registration registration;
  Skyline skyline;
  RegistrationOptions options;  // as used: priors, opening-angle window
  std::string fov_source;       // "--hfov", "--hfov-range", "exif", "exif-crop-factor" (either with "-cropped": sensors.h FrameOf) or "default"
  int width = 0, height = 0;
  double skyline_ms = 0.0, match_ms = 0.0;
  // With PhotoOptions::refine_position: the position estimate (its horizon
  // is the one `registration` was made at) and the time it took, included
  // in match_ms.
  std::optional<PositionEstimate> position;
  double position_ms = 0.0;
  // With PhotoOptions::check_position and a registration to check: the
  // check (its time included in match_ms).
  std::optional<PositionCheck> position_check;
  // When the search refused the best pose only for a rival that fits almost
  // as well (ambiguity, misfit or evidence against it): the inner ridges'
  // check (ridge_check.h), whose ruled-out rivals the search then left out.
  std::optional<RidgeCheck> ridge_check;
  // The horizon the registration was made at: the refined position's, else the site's.
  const HorizonProfile& Horizon(const Site& site) const { return position ? position->horizon : site.horizon(); }
};

// The skyline extractor's options for this photo (the inclinometer's roll as a hint).
SkylineOptions PhotoSkylineOptions(const PhotoOptions& options);
// The opening angles searched for a width x height photo: --hfov +-3%, the
// --hfov-range, EXIF's 35 mm focal length +-10%, else min_deg / max_deg are
// left as they are (the default range). Returns the source: "--hfov",
// "--hfov-range", "exif" ("exif-crop-factor" when the 35 mm value is the
// lens's focal length times the body's crop factor) or "default".
std::string PhotoHfovWindow(const PhotoOptions& options, int width, int height, double& min_deg, double& max_deg);
// The opening angle the photo's EXIF 35 mm focal length gives at `width`
// when that is what the search is centred on (no --hfov, no range).
std::optional<double> PhotoExifHfovDeg(const PhotoOptions& options, int width, int height);
// How far `r`'s opening angle departs from the EXIF's, |fitted / EXIF - 1|
// (PositionCheckOptions::lens_departure); 0 without an EXIF focal length,
// with an opening angle given, or with a --camera (its focal length is used
// as given).
double LensDepartureFromExif(const PhotoOptions& options, const Registration& r, int width, int height);
// The registration options for a width x height photo at `site`.
RegistrationOptions PhotoRegistrationOptions(const Site& site, const PhotoOptions& options, int width, int height,
                                             std::string* fov_source = nullptr);
// The same for an eye given by its altitude (altitude_given) or its height
// above the ground, wherever it stands (the site only says which).
RegistrationOptions PhotoRegistrationOptions(bool altitude_given, const PhotoOptions& options, int width, int height,
                                             std::string* fov_source = nullptr);

// RegisterImage at the site's horizon; when that refuses the best pose only
// for a rival (RefusedForARival: ambiguity, misfit ratio or evidence), the
// inner ridges' check (CheckRidges over the site's ridges and the photo's
// edges) and, when it rules out some of the rivals, RegisterImage again
// without them (RegistrationOptions::ruled_out_rivals), its message saying
// so. The check, when made, goes to `check`. The position check (a wrong
// camera position) is the caller's, after it, as for any registration.
Registration RegisterImageWithRidges(const Site& site, const cv::Mat& image, const Skyline& skyline,
                                     const RegistrationOptions& options, std::optional<RidgeCheck>* check = nullptr);

// For a photo refused as ambiguous while its opening angle was unknown
// (fov_source "default": no EXIF focal length, no --hfov): a hint naming
// both opening angles, that --hfov or a narrow --hfov-range rules one out,
// when the rival's differs from the best pose's by more than 20% (without
// EXIF the rival is usually a narrow view elsewhere in the panorama; on the
// Columbia photos saved without EXIF, --hfov within 3% of the truth
// registers AK01b_20080811, a range of 40-70 deg does not). Else empty.
std::string UnknownFovHint(const Registration& r, const std::string& fov_source, int width);

// Registers an 8-bit BGR (or grey) photo taken at `site`; the stages run on
// `pool` when given (else on their own threads). Never throws for a photo
// that does not register (status no_match); throws InvalidArgument for bad
// options or an image that is not a photo.
PhotoRegistration RegisterPhoto(const Site& site, const cv::Mat& image, const PhotoOptions& options,
                                ThreadPool* pool = nullptr);

// The photo's skyline as the registration sees it (`register --skyline-out`):
// when registered, read again near the DEM horizon projected at the pose,
// inside the window the registration's DEM error model allows
// (ExpectedSkylineWindow, GuideSkyline); else the extracted one. `image` is
// the registered photo.
Skyline RegisteredSkyline(const Site& site, const cv::Mat& image, const PhotoRegistration& photo);

// PhotoOptions::refine_position's step of RegisterPhoto, after the
// registration at the site: RefinePosition from it, then the registration
// again at the estimate (RegisterImage, the whole decision). When that one
// fails the gates the given position and the first registration are kept
// (the report says why). Sets out.position and out.position_ms.
void RefinePhotoPosition(const Site& site, const cv::Mat& image, const PositionOptions& position_options,
                         const RegistrationOptions& ro, PhotoRegistration& out, ThreadPool* pool = nullptr);

// Whether registration r lies inside the pose given as PhotoOptions::initial
// (`constrained`: its prior's gate, WithinPrior, and its opening angles as
// the search admits them, 5% beyond min_hfov_deg .. max_hfov_deg).
bool WithinPose(const RegistrationOptions& constrained, const Registration& r);

// PhotoOptions::initial without a trusted position: `alone`, registered (or
// not) by the search with no prior, stands only inside the pose given
// (WithinPose); a registration outside is refused, and each answer says
// which way it went. Searched near the pose given, the search has almost no
// rival and its ambiguity test, what refuses most wrong positions' poses,
// goes blind (4 of 468 ring probes of the real photos registered 1.3-6 deg
// off).
Registration ConfirmedWithoutPrior(Registration alone, const RegistrationOptions& constrained);

// Register() of the image's skyline, then RecheckWithGuidedSkyline() when
// it is a near miss. Refused by both, the first look's answer is returned,
// its message saying why the second look did not change it.
Registration RegisterImage(const cv::Mat& image, const Skyline& skyline, const HorizonProfile& horizon,
                           const RegistrationOptions& options);

// A second look at a registration that failed because too little of the
// extracted skyline fits (at most 0.2 short of the share needed; residual
// test passed; ambiguity ratio at least 0.85 of the one needed, as the
// misread columns deflate it):
// where the extracted boundary lies more than the inlier tolerance *below*
// the horizon projected at the best pose (the colour model took terrain for
// sky, as with snow against a pale sky), the column is searched within twice
// the tolerance of the projection for a clear colour step with smooth sky
// above it; found steps replace those columns and the pose is refined again
// (RefinePose), and the search on the re-read skyline must register on its
// own (the whole decision, ambiguity and evidence included) at that pose.
// Only such columns are re-read: the extractor's sky is uniform, so a clear
// step inside it is structure, whereas the terrain below a projection is full
// of edges that would confirm any pose; null (hidden) columns stay null. A
// faint miss (0.2-0.3 short of the share, ambiguity at least 0.8 of the gate:
// a hazy far range) reads the null columns too, with a step threshold of 2.5
// times the sky's own step noise above the extracted boundary, within 9-15
// BGR instead of 15. The new pose must lie within 0.2 deg of the first one. Re-reading near a
// pose's own projection helps any pose, so that search's rival (the
// alternative of its ambiguity ratio) is re-read near its own projection and
// refined, and its misfit must still be at least 1.1 times the best's.
// Returns the new
// registration (registered or not), or nullopt when fewer than
// max(8, width / 32) columns were re-read.
std::optional<Registration> RecheckWithGuidedSkyline(const cv::Mat& image, const Skyline& skyline,
                                                     const HorizonProfile& horizon, const Registration& first,
                                                     const RegistrationOptions& options);

}  // namespace horizonreg
