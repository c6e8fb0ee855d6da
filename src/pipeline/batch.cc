// SPDX-License-Identifier: MIT
#include "pipeline/batch.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <unordered_map>

#include "camera/camera.h"
#include "pipeline/camera_file.h"
#include "pipeline/image_io.h"
#include "pipeline/position.h"
#include "pipeline/report.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg {

namespace fs = std::filesystem;

namespace {

const char* const kManifestColumns[] = {"image",  "lat",     "lon",     "alt_m",  "agl_m",
                                        "hfov_deg", "camera", "sensors", "station", "initial"};
const char* const kStationColumns[] = {"station", "lat", "lon", "alt_m", "agl_m", "hfov_deg", "camera"};

// One record of a manifest or stations file: column -> text ("" = absent).
using Record = std::map<std::string, std::string>;

[[noreturn]] void Bad(const std::string& what, const std::string& path, int line, const std::string& why) {
  throw InvalidArgument(what + " '" + path + "'" + (line > 0 ? ", line " + std::to_string(line) : "") + ": " + why);
}

std::vector<std::pair<int, Record>> RecordsFromJson(const std::string& what, const std::string& path,
                                                    nlohmann::json root, const std::vector<std::string>& known,
                                                    const std::string& json_key) {
  std::vector<std::pair<int, Record>> out;
  const auto check_column = [&](const std::string& name, int entry) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      Bad(what, path, 0, "entry " + std::to_string(entry) + ": unknown key '" + name + "' (known: " + list + ")");
    }
  };
  if (root.is_object() && root.contains(json_key)) root = root[json_key];
  if (!root.is_array()) Bad(what, path, 0, "expected a JSON array of objects (or {\"" + json_key + "\": [...]})");
  int index = 0;
  for (const auto& o : root) {
    ++index;
    if (!o.is_object()) Bad(what, path, 0, "entry " + std::to_string(index) + " is not an object");
    Record r;
    for (const auto& [k, v] : o.items()) {
      check_column(k, index);
      if (v.is_null()) continue;
      if (v.is_string()) r[k] = v.get<std::string>();
      else if (v.is_number()) r[k] = v.dump();
      else Bad(what, path, 0, "entry " + std::to_string(index) + ": '" + k + "' must be a string or a number");
    }
    out.emplace_back(index, std::move(r));
  }
  return out;
}

// Records of a CSV (header first) or JSON file (array of objects, or
// {"<key>": [...]}), with their line numbers; rejects unknown columns.
std::vector<std::pair<int, Record>> ReadRecords(const std::string& what, const std::string& path,
                                                const std::vector<std::string>& known, const std::string& json_key) {
  const std::string text = ReadTextFile(path, what);
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && (text[first] == '[' || text[first] == '{'))
    return RecordsFromJson(what, path, ParseJson(text, what, path), known, json_key);
  return ReadCsvRecords(text, what, path, known);
}

std::optional<double> Number(const std::string& what, const std::string& path, int line, const Record& r,
                             const std::string& key, double lo, double hi) {
  const auto it = r.find(key);
  if (it == r.end()) return std::nullopt;
  const auto v = ParseDouble(it->second);
  if (!v || !std::isfinite(*v)) Bad(what, path, line, key + " '" + it->second + "' is not a number");
  if (!(*v >= lo && *v <= hi))
    Bad(what, path, line, key + " " + it->second + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v;
}

std::string Text(const Record& r, const std::string& key) {
  const auto it = r.find(key);
  return it == r.end() ? std::string() : it->second;
}

std::string Resolve(const fs::path& base, const std::string& p) {
  if (p.empty()) return p;
  const fs::path q(p);
  return q.is_absolute() ? p : (base / q).lexically_normal().string();
}

bool IsImageFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".tif" || ext == ".tiff";
}

}  // namespace

std::map<std::string, BatchStation> ReadStations(const std::string& path) {
  const std::string what = "stations";
  const fs::path base = fs::path(path).parent_path();
  std::map<std::string, BatchStation> out;
  for (const auto& [line, r] : ReadRecords(what, path, {std::begin(kStationColumns), std::end(kStationColumns)}, "stations")) {
    BatchStation s;
    s.name = Text(r, "station");
    if (s.name.empty()) Bad(what, path, line, "no station name");
    const auto lat = Number(what, path, line, r, "lat", -90, 90), lon = Number(what, path, line, r, "lon", -180, 360);
    if (!lat || !lon) Bad(what, path, line, "station '" + s.name + "' needs lat and lon");
    s.lat = *lat, s.lon = *lon;
    s.alt_m = Number(what, path, line, r, "alt_m", -1000, 20000);
    s.agl_m = Number(what, path, line, r, "agl_m", 0, 20000);
    if (s.alt_m && s.agl_m) Bad(what, path, line, "give alt_m or agl_m, not both");
    s.hfov_deg = Number(what, path, line, r, "hfov_deg", 0.1, 169);
    s.camera_path = Resolve(base, Text(r, "camera"));
    if (!out.emplace(s.name, s).second) Bad(what, path, line, "station '" + s.name + "' listed twice");
  }
  return out;
}

namespace {

std::vector<BatchItem> ItemsFromRecords(const std::vector<std::pair<int, Record>>& records, const fs::path& base,
                                        const std::string& what, const std::string& path) {
  std::vector<BatchItem> items;
  for (const auto& [line, r] : records) {
    BatchItem it;
    it.line = line;
    it.image = Text(r, "image");
    if (it.image.empty()) Bad(what, path, line, "no image");
    it.image_path = Resolve(base, it.image);
    it.lat = Number(what, path, line, r, "lat", -90, 90);
    it.lon = Number(what, path, line, r, "lon", -180, 360);
    if (it.lat.has_value() != it.lon.has_value()) Bad(what, path, line, "lat and lon go together");
    it.alt_m = Number(what, path, line, r, "alt_m", -1000, 20000);
    it.agl_m = Number(what, path, line, r, "agl_m", 0, 20000);
    if (it.alt_m && it.agl_m) Bad(what, path, line, "give alt_m or agl_m, not both");
    it.hfov_deg = Number(what, path, line, r, "hfov_deg", 0.1, 169);
    it.camera_path = Resolve(base, Text(r, "camera"));
    it.sensors_path = Resolve(base, Text(r, "sensors"));
    it.station = Text(r, "station");
    if (const std::string init = Text(r, "initial"); !init.empty())
      it.initial = ParseInitialPose(init, what + " '" + path + "', line " + std::to_string(line) + ": initial");
    items.push_back(std::move(it));
  }
  if (items.empty()) throw InvalidArgument(what + " '" + path + "': no photos");
  return items;
}

// Duplicates; positions and defaults from the stations file.
void FinishItems(std::vector<BatchItem>& items, const std::string& what, const std::string& path,
                 const std::map<std::string, BatchStation>& stations) {
  std::set<std::string> seen;
  for (BatchItem& it : items) {
    if (!seen.insert(it.image).second) Bad(what, path, it.line, "image '" + it.image + "' is listed twice");
    if (it.lat || it.station.empty() || stations.empty()) continue;  // else: sensors or EXIF GPS at run time
    const auto s = stations.find(it.station);
    if (s == stations.end()) Bad(what, path, it.line, "station '" + it.station + "' is not in the stations file");
    it.lat = s->second.lat, it.lon = s->second.lon;
    if (!it.alt_m && !it.agl_m) it.alt_m = s->second.alt_m, it.agl_m = s->second.agl_m;
    if (!it.hfov_deg) it.hfov_deg = s->second.hfov_deg;
    if (it.camera_path.empty()) it.camera_path = s->second.camera_path;
  }
}

}  // namespace

std::vector<BatchItem> ReadManifest(const std::string& path, const std::map<std::string, BatchStation>& stations) {
  const std::string what = "manifest";
  std::vector<BatchItem> items;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    // A folder of images: its own (station from a one-station file) and its
    // subfolders' (station = the subfolder's name).
    std::vector<std::pair<std::string, std::string>> found;  // relative path, station
    for (const auto& e : fs::directory_iterator(path, ec)) {
      if (e.is_regular_file(ec) && IsImageFile(e.path())) {
        found.emplace_back(e.path().filename().string(), "");
      } else if (e.is_directory(ec)) {
        for (const auto& f : fs::directory_iterator(e.path(), ec))
          if (f.is_regular_file(ec) && IsImageFile(f.path()))
            found.emplace_back((e.path().filename() / f.path().filename()).string(), e.path().filename().string());
      }
    }
    if (ec) throw IoError("manifest: cannot list '" + path + "': " + ec.message());
    std::sort(found.begin(), found.end());
    if (found.empty()) throw InvalidArgument("manifest: folder '" + path + "' holds no images (.jpg .png .tif)");
    for (auto& [rel, station] : found) {
      BatchItem it;
      it.image = rel;
      it.image_path = (fs::path(path) / rel).string();
      it.station = station.empty() && stations.size() == 1 ? stations.begin()->first : station;
      items.push_back(std::move(it));
    }
  } else {
    items = ItemsFromRecords(ReadRecords(what, path, {std::begin(kManifestColumns), std::end(kManifestColumns)}, "photos"),
                             fs::path(path).parent_path(), what, path);
  }
  FinishItems(items, what, path, stations);
  return items;
}

std::vector<BatchItem> ManifestFromJson(const nlohmann::json& rows, const std::string& base_dir,
                                        const std::string& source,
                                        const std::map<std::string, BatchStation>& stations) {
  const std::string what = "manifest";
  std::vector<BatchItem> items = ItemsFromRecords(
      RecordsFromJson(what, source, rows, {std::begin(kManifestColumns), std::end(kManifestColumns)}, "photos"),
      fs::path(base_dir), what, source);
  FinishItems(items, what, source, stations);
  return items;
}

void BatchOptions::Check() const {
  if (dem.empty() && !dem_for) throw InvalidArgument("batch: no DEM (give --dem or --dem-dir)");
  site.Check();
  photo.Check();
  if (refine_position && photo.position_sigma_m && !(*photo.position_sigma_m > 0.0))
    ThrowField("BatchOptions::photo.position_sigma_m", *photo.position_sigma_m, "> 0 with refine_position");
}

namespace {

// What a photo needs before its station is known.
struct Prepared {
  PhotoPosition position;
  SensorReading sensors, exif;
  std::string error;
};

std::string StationKey(const PhotoPosition& p) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), "%.7f,%.7f,%s,%s", p.lat_deg, p.lon_deg,
                p.agl_m ? std::to_string(*p.agl_m).c_str() : "-", p.alt_m ? std::to_string(*p.alt_m).c_str() : "-");
  return buf;
}

nlohmann::json ErrorRow(const BatchItem& item, const std::string& message) {
  nlohmann::json row = {{"image", item.image}, {"status", "error"}, {"message", message}};
  if (!item.station.empty()) row["station"] = item.station;
  return row;
}

// Whether a station's position has been vouched for by its photos: at
// least kVouchPhotos registered and passed the full position check (wide
// look included where their first ring asked for it), and none was refused
// by it (a pose the inner ridges chose, refused only under their stricter
// limit, is doubted itself, not the position). A wrong position is refused
// by the check on most photos (the real photos from 2-10 km away: every
// probe that registered before the check); one that fooled it on one photo
// is refused on another before the station is vouched for.
constexpr int kVouchPhotos = 2;
constexpr size_t kVouchChunk = kVouchPhotos;  // photos registered with the full check at a time ...
constexpr size_t kVouchTries = 8;             // ... up to this many

struct StationVouch {
  int passed = 0, refused = 0;
  std::vector<std::pair<double, double>> views;  // the passed photos' opening angles and aspect ratios
  void Add(const PhotoRegistration& r) {
    if (!r.position_check) return;
    if (!r.position_check->consistent && !r.position_check->only_ridges_limit) {
      ++refused;
    } else if (r.registration.registered) {
      ++passed;
      views.emplace_back(HfovFromFocalDeg(r.registration.focal_px, r.width), static_cast<double>(r.width) / r.height);
    }
  }
  bool Vouched() const { return refused == 0 && passed >= kVouchPhotos; }
  std::optional<double> OpeningAngle(double aspect) const { return AgreedOpeningAngle(views, aspect, kVouchPhotos); }
};

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::optional<double> AgreedOpeningAngle(const std::vector<std::pair<double, double>>& views, double aspect,
                                         int min_views) {
  std::vector<double> h;
  for (const auto& [hfov, a] : views)
    if (std::abs(a / aspect - 1.0) <= 0.01 && hfov > 0.0) h.push_back(hfov);
  if (h.empty() || static_cast<int>(h.size()) < min_views) return std::nullopt;
  std::sort(h.begin(), h.end());
  if (!(h.back() <= 1.02 * h.front())) return std::nullopt;
  return h[(h.size() - 1) / 2];
}

size_t RunBatch(const std::vector<BatchItem>& items, const BatchOptions& options, ThreadPool& pool,
                const std::function<void(const BatchResult&)>& on_row,
                const std::function<void(const BatchProgress&)>& on_progress) {
  options.Check();
  const auto t0 = std::chrono::steady_clock::now();
  std::mutex mutex;
  BatchProgress progress;
  progress.total = items.size();
  const auto emit = [&](BatchResult result) {
    on_row(result);  // concurrently: the caller serialises its writes
    std::lock_guard<std::mutex> lock(mutex);
    const std::string status = result.row.value("status", "");
    ++progress.done;
    progress.registered += status == "registered";
    progress.errors += status == "error";
    progress.elapsed_s = SecondsSince(t0);
    if (on_progress) on_progress(progress);
  };
  const auto error_message = [](const std::exception& e, bool ours) {
    return ours ? std::string(e.what()) : std::string("internal error: ") + e.what();
  };

  // The position of every photo (its row's, its station's, else its
  // sensors file's or EXIF GPS).
  std::vector<Prepared> prepared(items.size());
  pool.ParallelFor(items.size(), [&](size_t i, int) {
    const BatchItem& it = items[i];
    Prepared& p = prepared[i];
    try {
      if (!it.sensors_path.empty()) p.sensors = ReadSensorJson(it.sensors_path);
      if (options.use_exif) p.exif = ReadExif(it.image_path);
      p.position = ResolvePhotoPosition(it.lat, it.lon, it.agl_m, it.alt_m, p.sensors, p.exif, it.image);
    } catch (const Error& e) {
      p.error = error_message(e, true);
    } catch (const std::exception& e) {
      p.error = error_message(e, false);
    }
  });
  std::vector<std::string> keys;
  std::unordered_map<std::string, std::vector<size_t>> stations;
  for (size_t i = 0; i < items.size(); ++i) {
    if (!prepared[i].error.empty()) {
      emit({&items[i], ErrorRow(items[i], prepared[i].error)});
      continue;
    }
    const std::string key = StationKey(prepared[i].position);
    auto [where, fresh] = stations.try_emplace(key);
    if (fresh) keys.push_back(key);
    where->second.push_back(i);
  }

  for (const std::string& key : keys) {
    const std::vector<size_t>& members = stations[key];
    const PhotoPosition& pos = prepared[members.front()].position;
    std::unique_ptr<Site> site;
    try {
      SiteOptions so = options.site;
      so.agl_m = pos.agl_m, so.alt_m = pos.alt_m;
      const std::vector<std::string> dem =
          options.dem_for ? options.dem_for(pos.lat_deg, pos.lon_deg, so.max_distance_m) : options.dem;
      site = std::make_unique<Site>(dem, pos.lat_deg, pos.lon_deg, so, &pool);
    } catch (const std::exception& e) {
      const std::string m = error_message(e, dynamic_cast<const Error*>(&e) != nullptr);
      for (size_t i : members) emit({&items[i], ErrorRow(items[i], m)});
      continue;
    }
    // A station's position, once vouched for (StationVouch), spares its
    // later photos the position check's wide look.
    StationVouch vouch;
    std::mutex vouch_mutex;
    auto register_one = [&](size_t m, bool light) {
      const size_t i = members[m];
      const BatchItem& it = items[i];
      const Prepared& p = prepared[i];
      const auto p0 = std::chrono::steady_clock::now();
      try {
        std::vector<std::string> warnings;
        const cv::Mat image = ReadImage(it.image_path, options.max_image_pixels, &warnings);
        PhotoOptions po = options.photo;
        po.sensors = p.sensors;
        po.exif = p.exif;
        po.position_source = p.position.source;
        if (it.hfov_deg) po.hfov_deg = it.hfov_deg, po.hfov_range_deg.reset();
        if (it.initial) po.initial = it.initial;
        if (!it.camera_path.empty()) po.camera = ReadCameraFile(it.camera_path, image.cols, image.rows);
        if (options.refine_position)
          po.refine_position = DefaultPositionOptions(p.position.source,
                                                      p.position.alt_m && p.position.source == "exif",
                                                      options.photo.position_sigma_m);
        if (light && po.check_position) po.check_position->wide_radius_m = 0.0;
        PhotoRegistration r = RegisterPhoto(*site, image, po, &pool);
        // A vouched station's photo that found no pose with the opening
        // angle unknown or from its EXIF (+-10%), none given: again within
        // the station camera's (+-3%, as --hfov), which rules out the rivals
        // at other opening angles (zoomed-in views of other ranges). Not
        // one the position check refused: that answer stands (but for a
        // pose the inner ridges chose, refused under their stricter limit
        // only: that doubts the pose, not the station's position).
        const bool refused = r.position_check && !r.position_check->consistent && !r.position_check->only_ridges_limit;
        if (light && !r.registration.registered && !refused && !po.hfov_deg && !po.hfov_range_deg && !po.camera &&
            !po.initial)
          if (const std::optional<double> hfov = vouch.OpeningAngle(static_cast<double>(image.cols) / image.rows)) {
            PhotoOptions again = po;
            again.hfov_deg = *hfov;
            again.skyline = r.skyline;  // the same photo's: not extracted again (its time counted once)
            PhotoRegistration s = RegisterPhoto(*site, image, again, &pool);
            if (s.registration.registered) {
              s.fov_source = "station";
              s.skyline_ms = r.skyline_ms;
              r = std::move(s);
            }
          }
        if (!light) {
          std::lock_guard<std::mutex> lock(vouch_mutex);
          vouch.Add(r);
        }
        nlohmann::json row = RegistrationReport(*site, r, p.position.source, SecondsSince(p0) * 1000.0);
        if (light && row.contains("position_check")) row["position_check"]["station_vouched_by"] = vouch.passed;
        row["image"] = it.image;
        if (!it.station.empty()) row["station"] = it.station;
        if (!warnings.empty()) row["warnings"] = warnings;
        if (options.skylines) row["skyline"] = SkylineJson(RegisteredSkyline(*site, image, r));
        emit({&it, std::move(row), &image, site.get(), &r});
      } catch (const Error& e) {
        emit({&it, ErrorRow(it, error_message(e, true))});
      } catch (const std::exception& e) {
        emit({&it, ErrorRow(it, error_message(e, false))});
      }
    };
    // In manifest order, a few photos at a time with the full check until
    // the station is vouched for, then the rest with the light one (the
    // same rows whatever the number of threads). A station that cannot be
    // vouched for any more (a photo refused) or that its first
    // kVouchTries photos have not vouched for (night, fog: no_match) runs
    // the rest at once with the full check.
    size_t next = 0;
    while (options.vouch_stations && next < members.size() && next < kVouchTries && vouch.refused == 0 &&
           !vouch.Vouched()) {
      const size_t n = std::min(kVouchChunk, members.size() - next);
      pool.ParallelFor(n, [&](size_t k, int) { register_one(next + k, false); });
      next += n;
    }
    const bool light = options.vouch_stations && vouch.Vouched();
    pool.ParallelFor(members.size() - next, [&](size_t k, int) { register_one(next + k, light); });
  }
  return progress.done;
}

namespace {
const char* const kCsvColumns[] = {"image",        "station",       "status",           "azimuth_deg",
                                   "pitch_deg",    "roll_deg",      "hfov_deg",         "center_azimuth_deg",
                                   "center_elevation_deg", "focal_px", "azimuth_sigma_deg", "pitch_sigma_deg",
                                   "roll_sigma_deg", "rms_px",      "inlier_fraction",  "lat",
                                   "lon",          "eye_height_m",  "total_ms",         "message",
                                   "refined_lat",  "refined_lon",   "refined_eye_height_m"};

std::string CsvCell(const nlohmann::json& v) {
  if (v.is_null()) return "";
  std::string s = v.is_string() ? v.get<std::string>() : v.dump();
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' || c == '\r' ? ' ' : c);
  return q + "\"";
}
}  // namespace

std::string BatchCsvHeader() {
  std::string h;
  for (const char* c : kCsvColumns) h += (h.empty() ? "" : ",") + std::string(c);
  return h;
}

std::string BatchCsvLine(const nlohmann::json& row) {
  const auto get = [&](const char* key) -> nlohmann::json { return row.contains(key) ? row[key] : nlohmann::json(); };
  const auto sub = [&](const char* a, const char* b) -> nlohmann::json {
    return row.contains(a) && row[a].is_object() && row[a].contains(b) ? row[a][b] : nlohmann::json();
  };
  std::vector<nlohmann::json> cells = {get("image"),     get("station"),   get("status"),
                                       get("azimuth_deg"), get("pitch_deg"), get("roll_deg"),
                                       get("hfov_deg"),  sub("center_ray", "azimuth_deg"),
                                       sub("center_ray", "elevation_deg"), get("focal_px"),
                                       get("azimuth_sigma_deg"), get("pitch_sigma_deg"), get("roll_sigma_deg"),
                                       get("rms_px"),    get("inlier_fraction"), sub("observer", "lat"),
                                       sub("observer", "lon"), sub("observer", "eye_height_m"),
                                       sub("timing_ms", "total"), get("message"),
                                       sub("position", "lat"), sub("position", "lon"),
                                       sub("position", "eye_height_m")};
  std::string line;
  for (size_t i = 0; i < cells.size(); ++i) line += (i ? "," : "") + CsvCell(cells[i]);
  return line;
}

}  // namespace horizonreg
