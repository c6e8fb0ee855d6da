// SPDX-License-Identifier: MIT
// `horizonreg batch`: every photo of a manifest (or a folder) registered,
// one JSON line per photo; resumable after any interruption.
#include <fcntl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <thread>

#include "cli/commands.h"
#include "cli/guard.h"
#include "cli/image_io.h"
#include "cli/output.h"
#include "dem/tiles.h"
#include "pipeline/batch.h"
#include "pipeline/report.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg::cli {

namespace fs = std::filesystem;

void AddBatchCommand(CLI::App& app, BatchArgs& a) {
  CLI::App* c = app.add_subcommand(
      "batch", "Register every photo of a manifest or folder: one JSON line per photo, resumable, in parallel");
  c->add_option("manifest", a.manifest,
                "CSV or JSON manifest (columns image,lat,lon[,alt_m|agl_m][,hfov_deg][,camera][,sensors][,station]"
                "[,initial]; paths relative to it), or a folder of images (subfolders = stations)")
      ->required();
  auto* dem = c->add_option("--dem", a.dem, "DEM file(s), any GDAL format; several files form a mosaic");
  auto* dir = c->add_option("--dem-dir", a.dem_dir,
                            "Folder of DEM tiles (HGT, GeoTIFF, DTED, VRT, ...): the tiles around each station are "
                            "found by their extents");
  dem->excludes(dir);
  c->add_flag("--sea-level-fill", a.sea_level_fill,
              "Ground missing from every DEM file is the sea at 0 m (coastal stations, missing SRTM tiles)");
  c->add_option("--stations", a.stations, "Stations file: station,lat,lon[,alt_m|agl_m][,hfov_deg][,camera]");
  c->add_option("-o,--output", a.output, "JSON Lines output (appended to and resumed when it exists)")->required();
  c->add_option("--csv", a.csv, "Also write a CSV table of all the rows");
  c->add_option("--overlay-dir", a.overlay_dir, "Draw each photo's overlay (or skyline debug image) into this folder");
  c->add_option("--landmarks", a.landmarks, "Named peaks for the overlay labels (GeoJSON or CSV)");
  c->add_option("--threads", a.threads, "Threads (default: all cores)")->check(CLI::Range(1, 256));
  auto* hfov = c->add_option("--hfov", a.hfov, "Opening angle of every photo, degrees (a row's hfov_deg wins)");
  auto* range = c->add_option("--hfov-range", a.hfov_range, "Opening angles to search, MIN:MAX degrees");
  hfov->excludes(range);
  c->add_flag("--pinhole", a.pinhole, "The photos have no lens distortion: do not fit k1");
  c->add_flag("--no-exif", a.no_exif, "Ignore the photos' EXIF");
  c->add_flag("--refine-position", a.refine_position,
              "Also estimate each photo's latitude, longitude and eye height (as register --refine-position); "
              "rows gain the \"position\" block, the CSV refined_lat, refined_lon, refined_eye_height_m");
  c->add_flag("--skylines", a.skylines,
              "Rows also carry \"skyline\" (the skyline JSON; registered photos' read again near the DEM horizon at "
              "the pose, as register --skyline-out)");
  c->add_flag("--check-every-photo", a.check_every_photo,
              "Register every photo on its own, the position check's wide look included (by default, once two "
              "photos of a station have registered and passed the check and none was refused, the rest skip its wide "
              "look and, finding no pose, are tried again within the station camera's opening angle)");
  c->add_option("--position-sigma", a.position_sigma,
                "How far the positions may be off, metres, 1 sigma (default by each row's source, as register's)")
      ->check(CLI::Range(0.0, 100000.0));
  c->add_option("--step", a.step, "Azimuth step of the DEM horizon, degrees")->capture_default_str();
  c->add_option("--refraction", a.refraction, "Refraction coefficient k")->capture_default_str();
  c->add_option("--max-distance", a.max_distance, "Terrain farther than this is ignored, metres")
      ->capture_default_str();
  c->add_flag("--no-progress", a.no_progress, "No progress line on a terminal");
  AddMaxImageOption(*c, a.max_image_mpx);
  AddMaxDemOption(*c, a.max_dem_mb);
}

namespace {

// The rows already in the output, by image; cuts a half-written last line
// (an interrupted run) so that appending continues on a line boundary.
std::set<std::string> ResumeOutput(const std::string& path, size_t* rows) {
  std::set<std::string> done;
  *rows = 0;
  std::error_code ec;
  if (!fs::exists(path, ec)) return done;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("batch: cannot open '" + path + "'");
  std::string s;
  size_t complete = 0;  // bytes up to the end of the last whole line
  int line = 0;
  while (std::getline(in, s)) {
    if (in.eof()) break;  // no newline after it: half-written
    complete += s.size() + 1;
    ++line;
    if (Trim(s).empty()) continue;
    nlohmann::json row;
    try {
      row = nlohmann::json::parse(s);
    } catch (const nlohmann::json::exception&) {
      throw InvalidArgument("batch: '" + path + "' line " + std::to_string(line) +
                            " is not a JSON row; not resuming into it (give another -o)");
    }
    if (!row.is_object() || !row.contains("image") || !row["image"].is_string())
      throw InvalidArgument("batch: '" + path + "' line " + std::to_string(line) +
                            " is not a batch row; not resuming into it (give another -o)");
    done.insert(row["image"].get<std::string>());
    ++*rows;
  }
  in.close();
  if (complete < fs::file_size(path, ec) && !ec) {
    fs::resize_file(path, complete, ec);
    if (ec) throw IoError("batch: cannot cut the half-written last line of '" + path + "': " + ec.message());
  }
  return done;
}

void WriteCsv(const std::string& jsonl, const std::string& csv) {
  std::ifstream in(jsonl, std::ios::binary);
  if (!in) throw IoError("batch: cannot open '" + jsonl + "'");
  std::string out = BatchCsvHeader() + "\n", s;
  while (std::getline(in, s))
    if (!Trim(s).empty()) out += BatchCsvLine(nlohmann::json::parse(s)) + "\n";
  WriteOutput(csv, out);
}

std::string Duration(double s) {
  if (!std::isfinite(s) || s < 0) return "--:--";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof(buf), "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
  else
    std::snprintf(buf, sizeof(buf), "%ld:%02ld", t / 60, t % 60);
  return buf;
}

std::string OverlayName(const std::string& image) {
  std::string s = fs::path(image).replace_extension(".png").string();
  for (char& c : s)
    if (c == '/' || c == '\\') c = '_';
  while (!s.empty() && (s[0] == '.' || s[0] == '_')) s.erase(0, 1);  // "../x", "/abs/x": no hidden or odd names
  return s;
}

}  // namespace

int RunBatch(const BatchArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::map<std::string, BatchStation> stations =
      a.stations.empty() ? std::map<std::string, BatchStation>{} : ReadStations(a.stations);
  const std::vector<BatchItem> all = ReadManifest(a.manifest, stations);
  BatchOptions o;
  o.dem = a.dem;
  if (!a.dem_dir.empty()) {
    const DemTileIndex index(a.dem_dir);  // the folder's tiles and their extents, read once
    o.dem_for = [index](double lat, double lon, double max_distance_m) {
      return index.TilesAround(lat, lon, max_distance_m);
    };
  }
  o.site.sea_level_fill = a.sea_level_fill;
  o.site.max_dem_bytes = static_cast<size_t>(a.max_dem_mb * (1 << 20));
  o.max_image_pixels = a.max_image_mpx * 1e6;
  o.site.azimuth_step_deg = a.step;
  o.site.refraction = a.refraction;
  o.site.max_distance_m = a.max_distance;
  o.photo.hfov_deg = a.hfov;
  if (!a.hfov_range.empty()) o.photo.hfov_range_deg = ParseHfovRange(a.hfov_range);
  o.photo.pinhole = a.pinhole;
  o.use_exif = !a.no_exif;
  if (a.refine_position && a.position_sigma && !(*a.position_sigma > 0.0))
    throw InvalidArgument("--position-sigma must be > 0 with --refine-position");
  o.photo.position_sigma_m = a.position_sigma;
  o.refine_position = a.refine_position;
  o.skylines = a.skylines;
  o.vouch_stations = !a.check_every_photo;
  o.Check();
  if (!a.overlay_dir.empty()) {
    std::error_code ec;
    fs::create_directories(a.overlay_dir, ec);
    if (ec) throw IoError("batch: cannot create '" + a.overlay_dir + "': " + ec.message());
  }

  size_t previous = 0;
  const std::set<std::string> done = ResumeOutput(a.output, &previous);
  std::vector<BatchItem> todo;
  for (const BatchItem& it : all)
    if (!done.count(it.image)) todo.push_back(it);
  const int fd = ::open(a.output.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw IoError("batch: cannot open '" + a.output + "': " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};

  std::mutex write_mutex;
  std::string write_error;
  const bool tty = !a.no_progress && ::isatty(STDERR_FILENO);
  double last_shown = -1.0;
  const int threads = a.threads.value_or(std::max(1u, std::thread::hardware_concurrency()));
  ThreadPool pool(threads);
  BatchProgress final_progress;
  RunBatch(
      todo, o, pool,
      [&](const BatchResult& r) {
        if (!a.overlay_dir.empty() && r.registration) {
          try {
            WriteImage((fs::path(a.overlay_dir) / OverlayName(r.item->image)).string(),
                       DrawRegistration(*r.site, *r.image, *r.registration, a.landmarks));
          } catch (const std::exception& e) {
            std::lock_guard<std::mutex> lock(write_mutex);
            if (write_error.empty()) write_error = e.what();
          }
        }
        // One write() per row, appended: a kill leaves at most a partial
        // last line, which the next run cuts.
        const std::string line = r.row.dump() + "\n";
        std::lock_guard<std::mutex> lock(write_mutex);
        size_t off = 0;
        while (off < line.size()) {
          const ssize_t n = ::write(fd, line.data() + off, line.size() - off);
          if (n < 0 && errno == EINTR) continue;
          if (n <= 0) {
            if (write_error.empty()) write_error = "cannot write '" + a.output + "': " + std::strerror(errno);
            break;
          }
          off += static_cast<size_t>(n);
        }
      },
      [&](const BatchProgress& p) {
        final_progress = p;
        if (!tty || (p.elapsed_s - last_shown < 0.25 && p.done < p.total)) return;
        last_shown = p.elapsed_s;
        const double rate = p.done / std::max(1e-9, p.elapsed_s);
        std::fprintf(stderr, "\rbatch %zu/%zu (%.1f%%)  %.1f photos/s  ETA %s  registered %zu  errors %zu   ", p.done,
                     p.total, 100.0 * p.done / std::max<size_t>(1, p.total), rate,
                     Duration((p.total - p.done) / std::max(1e-9, rate)).c_str(), p.registered, p.errors);
        std::fflush(stderr);
      });
  if (tty && final_progress.done > 0) std::fprintf(stderr, "\n");
  if (!write_error.empty()) throw IoError("batch: " + write_error);
  if (!a.csv.empty()) WriteCsv(a.output, a.csv);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr,
               "batch: %zu photos (%zu already done), %zu registered, %zu no_match, %zu errors in %.1f s "
               "(%.1f photos/s); rows in %s\n",
               todo.size(), previous, final_progress.registered,
               final_progress.done - final_progress.registered - final_progress.errors, final_progress.errors, secs,
               todo.size() / std::max(1e-9, secs), a.output.c_str());
  return 0;
}

}  // namespace horizonreg::cli
