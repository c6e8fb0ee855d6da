// SPDX-License-Identifier: MIT
#include "dem/tiles.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>

#include "util/errors.h"

namespace horizonreg {

namespace fs = std::filesystem;

namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool IsDemFile(const fs::path& p) {
  static const std::set<std::string> kExt = {".hgt", ".tif", ".tiff", ".dt0", ".dt1", ".dt2",
                                             ".dem", ".bt",  ".vrt",  ".img", ".npz"};
  return kExt.count(Lower(p.extension().string())) > 0;
}

// Smallest distance in metres from (lat, lon) to a box (0 inside), on a sphere's local scale.
double DistanceToBoxM(const GeoBox& b, double lat, double lon) {
  const double dlat = lat < b.south ? b.south - lat : (lat > b.north ? lat - b.north : 0.0);
  double dlon = 0.0;
  for (double shift : {-360.0, 0.0, 360.0}) {
    const double l = lon + shift;
    const double d = l < b.west ? b.west - l : (l > b.east ? l - b.east : 0.0);
    dlon = shift == -360.0 ? d : std::min(dlon, d);
  }
  const double near_lat = std::clamp(lat, b.south, b.north);
  constexpr double kMPerDeg = 111'195.0;
  return std::hypot(dlat * kMPerDeg, dlon * kMPerDeg * std::cos(near_lat * M_PI / 180.0));
}

}  // namespace

bool HgtNameExtent(const std::string& file_name, GeoBox& box) {
  const std::string n = Lower(fs::path(file_name).filename().string());
  // [ns]DD[ew]DDD.hgt
  if (n.size() != 11 || n.compare(7, 4, ".hgt") != 0) return false;
  const auto digits = [&](size_t from, size_t count) {
    for (size_t i = from; i < from + count; ++i)
      if (!std::isdigit(static_cast<unsigned char>(n[i]))) return false;
    return true;
  };
  const char ns = n[0], ew = n[3];
  if ((ns != 'n' && ns != 's') || (ew != 'e' && ew != 'w') || !digits(1, 2) || !digits(4, 3)) return false;
  const int lat = std::stoi(n.substr(1, 2)), lon = std::stoi(n.substr(4, 3));
  if (lat > 89 || lon > 180) return false;
  const double s = ns == 'n' ? lat : -lat, w = ew == 'e' ? lon : -lon;
  box = {s, s + 1.0, w, w + 1.0};
  return true;
}

DemTileIndex::DemTileIndex(const std::string& dir) : dir_(dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IoError("--dem-dir: '" + dir + "' is not a folder");
  std::vector<std::string> files;
  for (auto it = fs::recursive_directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
    if (it->is_regular_file(ec) && IsDemFile(it->path())) files.push_back(it->path().lexically_normal().string());
  if (ec) throw IoError("--dem-dir: cannot list '" + dir + "': " + ec.message());
  std::sort(files.begin(), files.end());
  std::set<std::string> in_vrt;
  std::vector<std::pair<std::string, GeoBox>> found;
  for (const std::string& f : files) {
    GeoBox box;
    if (HgtNameExtent(f, box)) {
      found.emplace_back(f, box);
      continue;
    }
    const Terrain t({f});  // metadata only
    found.emplace_back(f, t.ExtentOf(0));
    if (Lower(fs::path(f).extension().string()) == ".vrt")
      for (const std::string& src : t.SourceFilesOf(0)) {
        const fs::path p = fs::weakly_canonical(src, ec);
        if (!ec) in_vrt.insert(p.string());
      }
  }
  for (auto& [f, box] : found) {
    const fs::path p = fs::weakly_canonical(f, ec);
    if (Lower(fs::path(f).extension().string()) != ".vrt" && !ec && in_vrt.count(p.string())) continue;
    tiles_.emplace_back(f, box);
  }
  if (tiles_.empty()) throw IoError("--dem-dir: '" + dir + "' holds no DEM file (.hgt .tif .dt1 .dem .bt .vrt ...)");
}

std::vector<std::string> DemTileIndex::TilesAround(double lat, double lon, double radius_m) const {
  std::vector<std::string> out;
  bool covered = false;
  for (const auto& [f, box] : tiles_) {
    const double d = DistanceToBoxM(box, lat, lon);
    if (d <= radius_m) out.push_back(f);
    covered = covered || d == 0.0;
  }
  if (!covered) {
    std::ostringstream m;
    m.precision(8);
    m << "--dem-dir: no tile in '" << dir_ << "' covers (" << lat << ", " << lon << ")";
    throw InvalidArgument(m.str());
  }
  return out;
}

std::vector<std::string> DemFilesFor(const std::vector<std::string>& dem, const std::string& dem_dir, double lat_deg,
                                     double lon_deg, double radius_m) {
  if (!dem.empty() && !dem_dir.empty()) throw InvalidArgument("give --dem files or --dem-dir, not both");
  if (dem.empty() && dem_dir.empty()) throw InvalidArgument("no DEM: give --dem FILE or --dem-dir DIR");
  if (!dem.empty()) return dem;
  return DemTileIndex(dem_dir).TilesAround(lat_deg, lon_deg, radius_m);
}

}  // namespace horizonreg
