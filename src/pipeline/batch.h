// SPDX-License-Identifier: MIT
// Registering an archive of photos: a manifest (CSV or JSON) or a folder of
// images with a stations file; photos taken at one position (a station)
// share one Site; photos run in parallel on one pool; one JSON row per photo
// (the register JSON plus "image"), an error row for a photo that cannot be
// read, and the batch goes on.
#pragma once

#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/image_io.h"
#include "pipeline/register_photo.h"
#include "pipeline/site.h"
#include "util/thread_pool.h"

namespace cv {
class Mat;
}

namespace horizonreg {

// One photo of a batch. Paths are resolved against the manifest's folder;
// `image` keeps the manifest's text (the row's key in the output).
struct BatchItem {
  std::string image;       // as written in the manifest (or relative to the folder)
  std::string image_path;  // resolved
  std::optional<double> lat, lon, alt_m, agl_m, hfov_deg;
  std::string camera_path, sensors_path, station;
  std::optional<InitialPose> initial;
  int line = 0;  // manifest line (CSV) or array index + 1 (JSON), for messages
};

// A station of a stations file: name, position, optional defaults for its photos.
struct BatchStation {
  std::string name;
  double lat = NAN, lon = NAN;
  std::optional<double> alt_m, agl_m, hfov_deg;
  std::string camera_path;
};

// Reads a stations CSV (`station,lat,lon[,alt_m][,agl_m][,hfov_deg][,camera]`)
// or JSON (an array of such objects). Throws InvalidArgument naming the file
// and line.
std::map<std::string, BatchStation> ReadStations(const std::string& path);

// Reads a manifest: CSV with a header (`image` and optional `lat`, `lon`,
// `alt_m`, `agl_m`, `hfov_deg`, `camera`, `sensors`, `station`, `initial`),
// or JSON (an array of objects with the same keys, or {"photos": [...]});
// or, when `path` is a folder, every image in it (.jpg .jpeg .png .tif
// .tiff) and in its immediate subfolders, whose name is then the station.
// Rows without a position take their station's from `stations` (and its
// defaults); a row without either is registered from its sensors file or
// its EXIF GPS. Throws InvalidArgument naming the file and line for a
// malformed manifest, an unknown column, a bad number, an image listed
// twice or an unknown station.
std::vector<BatchItem> ReadManifest(const std::string& path, const std::map<std::string, BatchStation>& stations = {});

// The same from an already parsed JSON array of manifest objects (Python,
// Dask); relative paths are resolved against `base_dir`, `source` names the
// array in messages.
std::vector<BatchItem> ManifestFromJson(const nlohmann::json& rows, const std::string& base_dir,
                                        const std::string& source,
                                        const std::map<std::string, BatchStation>& stations = {});

struct BatchOptions {
  std::vector<std::string> dem;  // DEM files (a mosaic), or
  // the DEM files to use for a station at (lat, lon) (e.g. tiles found in a
  // folder); takes precedence over `dem` when set.
  std::function<std::vector<std::string>(double lat, double lon, double max_distance_m)> dem_for;
  SiteOptions site;    // step, refraction, distance (the position comes from each row)
  PhotoOptions photo;  // defaults for every photo (opening angle, pinhole, thresholds)
  bool use_exif = true;
  // Refine each photo's position too, within the prior its position's
  // source sets (DefaultPositionOptions; photo.position_sigma_m overrides
  // the horizontal sigma): each row then has the "position" block.
  bool refine_position = false;
  // Each row also carries "skyline" (DESIGN.md's skyline JSON): for a
  // registered photo read again near the DEM horizon at its pose
  // (RegisteredSkyline, as register --skyline-out), else the extracted one.
  bool skylines = false;
  // Photos of one station (one position) share its check: once two of them
  // have registered and passed the full position check, and none has been
  // refused by it, the station's later photos skip the check's wide look (the
  // grid of places out to 4 km, most of a real photo's time on a coarse DEM);
  // their first ring and pattern still run. Their rows' "position_check"
  // then carries "station_vouched_by" (how many photos passed). The first
  // photos go two at a time (up to 8 of them, until vouched for or one is
  // refused), so a station's first photos use at most two threads. A later
  // photo that finds no pose with its opening angle unknown or from its EXIF
  // (none given, no camera file, no initial pose) is registered again within
  // the station camera's (AgreedOpeningAngle of the photos that passed,
  // +-3% as --hfov); its row then says "station" in "hfov_search_deg".
  bool vouch_stations = true;
  double max_image_pixels = kDefaultMaxImagePixels;  // larger photos are error rows (ReadImage)
  void Check() const;
};

struct BatchProgress {
  size_t done = 0, total = 0, registered = 0, errors = 0;
  double elapsed_s = 0.0;
};

// What on_row receives once per photo, from the thread that registered it
// (calls are concurrent: on_row must be thread-safe): the row, and for
// photos without an error the image, site and registration (e.g. to draw an
// overlay), valid during the call.
struct BatchResult {
  const BatchItem* item = nullptr;
  nlohmann::json row;
  const cv::Mat* image = nullptr;
  const Site* site = nullptr;
  const PhotoRegistration* registration = nullptr;
};

// A fixed camera's opening angle from its registered photos (`views`:
// opening angle and aspect ratio, width over height, per photo): the median
// (the lower of the middle two) of those of this aspect ratio (within 1%)
// when at least min_views of them agree within 2%; none when fewer, or when
// they disagree (a zoom that moved).
std::optional<double> AgreedOpeningAngle(const std::vector<std::pair<double, double>>& views, double aspect,
                                         int min_views);

// Registers `items` on `pool`, station by station (the items sharing a
// position share a Site, built once). Never throws for a bad photo, sensors
// or camera file or a station whose DEM cannot be read: those become rows
// with "status": "error" and the message. on_progress is called after each
// row, serialised. Returns the number of rows.
size_t RunBatch(const std::vector<BatchItem>& items, const BatchOptions& options, ThreadPool& pool,
                const std::function<void(const BatchResult&)>& on_row,
                const std::function<void(const BatchProgress&)>& on_progress = {});

// The CSV header and one CSV line (no newline) of a batch row.
std::string BatchCsvHeader();
std::string BatchCsvLine(const nlohmann::json& row);

}  // namespace horizonreg
