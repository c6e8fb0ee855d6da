// SPDX-License-Identifier: MIT
#include "dem/terrain.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <gdal_alg.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <optional>
#include <sstream>

#include "dem/npz_dem.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

// GDAL prints its errors to stderr unless told otherwise; the library never
// prints, so errors are silenced and read back with CPLGetLastErrorMsg.
void EnsureGdalRegistered() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);
  });
}

namespace {

constexpr float kVoidSentinel = -1.0e30f;

std::string Quote(const std::string& s) { return "'" + s + "'"; }

std::string LastGdalMessage() {
  std::string msg = CPLGetLastErrorMsg();
  if (msg.empty()) return "unknown GDAL error";
  std::replace(msg.begin(), msg.end(), '\n', ' ');
  return msg;
}


struct SrsDeleter {
  void operator()(void* p) const { OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(p)); }
};
struct CtDeleter {
  void operator()(void* p) const { OCTDestroyCoordinateTransformation(static_cast<OGRCoordinateTransformationH>(p)); }
};
struct DatasetDeleter {
  void operator()(void* p) const { GDALClose(static_cast<GDALDatasetH>(p)); }
};

struct Source {
  std::string path;
  std::unique_ptr<void, DatasetDeleter> dataset;
  int width = 0, height = 0;
  double gt[6] = {0, 1, 0, 0, 0, 1};                      // GDAL geotransform (pixel corner based)
  bool separable = false;                                 // WGS84 geographic, north-up
  std::unique_ptr<void, CtDeleter> to_wgs84, from_wgs84;  // lon/lat order
  std::optional<double> nodata;

  double ColOfX(double x) const { return (x - gt[0]) / gt[1] - 0.5; }  // separable only
  double RowOfY(double y) const { return (y - gt[3]) / gt[5] - 0.5; }
};

std::unique_ptr<void, SrsDeleter> MakeWgs84() {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRSetWellKnownGeogCS(srs, "WGS84");
  OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
  return std::unique_ptr<void, SrsDeleter>(srs);
}

GDALDatasetH DatasetFromNpz(const std::string& path) {
  NpzDem npz = ReadNpzDem(path);
  GDALDriverH mem = GDALGetDriverByName("MEM");
  if (mem == nullptr) throw IoError("dem: GDAL has no MEM driver");
  GDALDatasetH ds = GDALCreate(mem, "", npz.width, npz.height, 1, GDT_Float64, nullptr);
  const double dx = (npz.east_deg - npz.west_deg) / (npz.width - 1);
  const double dy = (npz.north_deg - npz.south_deg) / (npz.height - 1);
  double gt[6] = {npz.west_deg - dx / 2, dx, 0.0, npz.north_deg + dy / 2, 0.0, -dy};
  GDALSetGeoTransform(ds, gt);
  auto wgs84 = MakeWgs84();
  GDALSetSpatialRef(ds, static_cast<OGRSpatialReferenceH>(wgs84.get()));
  if (GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Write, 0, 0, npz.width, npz.height, npz.elevation_m.data(), npz.width,
                   npz.height, GDT_Float64, 0, 0) != CE_None) {
    GDALClose(ds);
    throw IoError("dem: cannot store " + Quote(path) + " in memory: " + LastGdalMessage());
  }
  return ds;
}

// GDAL 3.6's SRTMHGT driver opens a zipped tile (N46E007.hgt.zip) by the
// member's size in the zip directory even when the member itself cannot be
// opened (a corrupt local header), and then reads through a null file
// handle, a crash (found by fuzz/fuzz_dem.cc): such a zip is refused here.
void CheckZippedHgtOpens(const std::string& path, GDALDatasetH ds) {
  const char* driver = GDALGetDriverShortName(GDALGetDatasetDriver(ds));
  if (driver == nullptr || std::string(driver) != "SRTMHGT") return;
  const std::string zip = "/vsizip/" + path;
  char** members = VSIReadDir(zip.c_str());
  if (members == nullptr) return;  // not a zip: the driver read the file itself
  std::string bad;
  for (int i = 0; members[i] != nullptr && bad.empty(); ++i) {
    VSILFILE* f = VSIFOpenL((zip + "/" + members[i]).c_str(), "rb");
    if (f == nullptr) bad = members[i];
    else VSIFCloseL(f);
  }
  CSLDestroy(members);
  if (!bad.empty()) throw IoError("dem: cannot read '" + bad + "' inside " + Quote(path) + ": " + LastGdalMessage());
}

Source OpenSource(const std::string& path) {
  Source s;
  s.path = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError("dem: cannot open " + Quote(path) + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError("dem: " + Quote(path) + " is a directory, not a DEM file");
  CPLErrorReset();
  GDALDatasetH ds;
  if (std::filesystem::path(path).extension() == ".npz") {
    ds = DatasetFromNpz(path);
  } else {
    ds = GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR, nullptr, nullptr, nullptr);
  }
  if (ds == nullptr) throw IoError("dem: " + Quote(path) + " is not a readable raster: " + LastGdalMessage());
  s.dataset.reset(ds);
  CheckZippedHgtOpens(path, ds);
  if (GDALGetRasterCount(ds) < 1) throw IoError("dem: " + Quote(path) + " has no raster band");
  s.width = GDALGetRasterXSize(ds);
  s.height = GDALGetRasterYSize(ds);
  if (s.width < 2 || s.height < 2) throw IoError("dem: " + Quote(path) + " has fewer than 2x2 posts");
  if (GDALGetGeoTransform(ds, s.gt) != CE_None || s.gt[1] == 0.0 || s.gt[5] == 0.0)
    throw IoError("dem: " + Quote(path) + " has no georeference (geotransform)");
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
  if (srs == nullptr) throw IoError("dem: " + Quote(path) + " has no coordinate reference system");
  std::unique_ptr<void, SrsDeleter> src_srs(OSRClone(srs));
  OSRSetAxisMappingStrategy(src_srs.get(), OAMS_TRADITIONAL_GIS_ORDER);
  auto wgs84 = MakeWgs84();
  const bool north_up = s.gt[2] == 0.0 && s.gt[4] == 0.0;
  s.separable = north_up && OSRIsGeographic(src_srs.get()) && OSRIsSameGeogCS(src_srs.get(), wgs84.get());
  if (!s.separable) {
    // One search for the operation, then its inverse: PROJ's search takes
    // 0.4 s (release; 3 s under ASan) for a datum it does not know, e.g. an
    // ellipsoid a little off WGS84's (fuzz_dem's timeouts: slow/dem/).
    s.to_wgs84.reset(OCTNewCoordinateTransformation(src_srs.get(), wgs84.get()));
    if (s.to_wgs84) s.from_wgs84.reset(OCTGetInverse(static_cast<OGRCoordinateTransformationH>(s.to_wgs84.get())));
    if (!s.to_wgs84 || !s.from_wgs84)
      throw IoError("dem: cannot transform the CRS of " + Quote(path) + " to WGS84: " + LastGdalMessage());
  }
  int has_nodata = 0;
  const double nd = GDALGetRasterNoDataValue(GDALGetRasterBand(ds, 1), &has_nodata);
  if (has_nodata) s.nodata = nd;
  return s;
}

// Geo (x, y) in the source CRS of a pixel-centre position (col, row).
void GeoOfPixel(const Source& s, double col, double row, double& x, double& y) {
  const double px = col + 0.5, py = row + 0.5;
  x = s.gt[0] + px * s.gt[1] + py * s.gt[2];
  y = s.gt[3] + px * s.gt[4] + py * s.gt[5];
}

// Pixel-centre position of a geo (x, y); inverts the geotransform.
void PixelOfGeo(const Source& s, double x, double y, double& col, double& row) {
  const double det = s.gt[1] * s.gt[5] - s.gt[2] * s.gt[4];
  const double dx = x - s.gt[0], dy = y - s.gt[3];
  col = (s.gt[5] * dx - s.gt[2] * dy) / det - 0.5;
  row = (-s.gt[4] * dx + s.gt[1] * dy) / det - 0.5;
}

// A longitude moved by whole turns next to a geographic source's tile, so
// that windows and lookups work across the antimeridian.
double LonNearTile(const Source& s, double lon_deg) {
  const double tile_mid = s.gt[0] + s.gt[1] * s.width / 2;
  return lon_deg + std::round((tile_mid - lon_deg) / 360.0) * 360.0;
}

// Pixel-centre (col, row) of a WGS84 position in a source; nullopt when the
// CRS transformation fails.
std::optional<std::pair<double, double>> PixelOfLatLon(const Source& s, double lat_deg, double lon_deg) {
  if (s.separable) return std::make_pair(s.ColOfX(LonNearTile(s, lon_deg)), s.RowOfY(lat_deg));
  double x = lon_deg, y = lat_deg, z = 0;
  if (!OCTTransform(static_cast<OGRCoordinateTransformationH>(s.from_wgs84.get()), 1, &x, &y, &z)) return std::nullopt;
  double col, row;
  PixelOfGeo(s, x, y, col, row);
  return std::make_pair(col, row);
}

struct PixelWindow {
  int c0 = 0, r0 = 0, c1 = -1, r1 = -1;  // inclusive
  bool empty() const { return c1 < c0 || r1 < r0; }
  int w() const { return c1 - c0 + 1; }
  int h() const { return r1 - r0 + 1; }
};

PixelWindow WindowOf(const Source& s, const GeodeticPoint& c, double radius_m) {
  double cmin, cmax, rmin, rmax;
  if (s.separable) {
    const double dlat = radius_m / 110000.0 + 1e-9;
    const double lat_hi = std::min(89.999, std::abs(c.lat_deg) + dlat);
    const double dlon = std::min(180.0, radius_m / (111000.0 * std::cos(DegToRad(lat_hi))));
    const double lon = LonNearTile(s, c.lon_deg);
    cmin = s.ColOfX(lon - dlon), cmax = s.ColOfX(lon + dlon);
    rmin = s.RowOfY(c.lat_deg + dlat), rmax = s.RowOfY(c.lat_deg - dlat);
  } else {
    const auto px = PixelOfLatLon(s, c.lat_deg, c.lon_deg);
    if (!px) return {};
    const auto [col, row] = *px;
    // Metres per pixel along each axis, from the geotransform (projected CRS in metres).
    const double px_m = std::min(std::hypot(s.gt[1], s.gt[4]), std::hypot(s.gt[2], s.gt[5]));
    const double half = radius_m / px_m * 1.02 + 2.0;
    cmin = col - half, cmax = col + half, rmin = row - half, rmax = row + half;
  }
  if (cmin > cmax) std::swap(cmin, cmax);
  if (rmin > rmax) std::swap(rmin, rmax);
  PixelWindow w;
  w.c0 = static_cast<int>(std::max(0.0, std::floor(cmin) - 1));
  w.c1 = static_cast<int>(std::min<double>(s.width - 1, std::ceil(cmax) + 1));
  w.r0 = static_cast<int>(std::max(0.0, std::floor(rmin) - 1));
  w.r1 = static_cast<int>(std::min<double>(s.height - 1, std::ceil(rmax) + 1));
  if (cmax < 0 || rmax < 0 || cmin > s.width - 1 || rmin > s.height - 1) return {};
  return w;
}

// Reads a window as float into dst (line stride dst_stride floats), nodata
// and implausible values as kVoidSentinel.
void ReadPosts(const Source& s, const PixelWindow& w, float* dst, size_t dst_stride) {
  CPLErrorReset();
  if (GDALRasterIO(GDALGetRasterBand(static_cast<GDALDatasetH>(s.dataset.get()), 1), GF_Read, w.c0, w.r0, w.w(), w.h(),
                   dst, w.w(), w.h(), GDT_Float32, 0, static_cast<GSpacing>(dst_stride * sizeof(float))) != CE_None)
    throw IoError("dem: cannot read " + Quote(s.path) + ": " + LastGdalMessage());
  const float nd = s.nodata ? static_cast<float>(*s.nodata) : 0.0f;
  const bool has_nd = s.nodata.has_value();
  for (int r = 0; r < w.h(); ++r) {
    float* row = dst + r * dst_stride;
    for (int c = 0; c < w.w(); ++c) {
      const float v = row[c];
      if (!(v >= -12000.0f && v <= 10000.0f) || (has_nd && v == nd)) row[c] = kVoidSentinel;
    }
  }
}

// Fills voids (kVoidSentinel) of a w x h buffer where covered[i]: holes are
// interpolated by one GDALFillNodata call (inverse distance). A void that
// spans more than 2 * kMaxVoidFillPx posts is a missing area, not a hole: it
// stays NaN, and so do holes next to it (their interpolation would lean on
// nothing), and everything not covered.
void FillVoids(std::vector<float>& buf, const std::vector<uint8_t>& covered, int w, int h, const std::string& what) {
  struct Box {
    int c0, c1, r0, r1;
  };
  std::vector<Box> big, small;
  std::vector<uint8_t> state(buf.size(), 0);  // 1: small void, 2: big void
  std::vector<int> stack, members;
  for (size_t start = 0; start < buf.size(); ++start) {
    if (buf[start] != kVoidSentinel || !covered[start] || state[start]) continue;
    Box b{w, -1, h, -1};
    members.clear();
    stack.assign(1, static_cast<int>(start));
    state[start] = 1;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      members.push_back(k);
      const int c = k % w, r = k / w;
      b.c0 = std::min(b.c0, c), b.c1 = std::max(b.c1, c), b.r0 = std::min(b.r0, r), b.r1 = std::max(b.r1, r);
      const int nb[4] = {c > 0 ? k - 1 : -1, c + 1 < w ? k + 1 : -1, r > 0 ? k - w : -1, r + 1 < h ? k + w : -1};
      for (int q : nb)
        if (q >= 0 && !state[q] && buf[q] == kVoidSentinel && covered[q]) state[q] = 1, stack.push_back(q);
    }
    if (b.c1 - b.c0 + 1 > 2 * kMaxVoidFillPx || b.r1 - b.r0 + 1 > 2 * kMaxVoidFillPx) {
      for (int k : members) state[k] = 2;
      big.push_back(b);
    } else {
      small.push_back(b);
    }
  }
  if (!small.empty()) {
    const int m = static_cast<int>(kMaxVoidFillPx);
    Box fill{w, -1, h, -1};  // bounding box of the holes to fill
    for (const Box& s : small) {
      bool near_big = false;
      for (const Box& b : big)
        near_big = near_big || !(s.c1 + m < b.c0 || b.c1 + m < s.c0 || s.r1 + m < b.r0 || b.r1 + m < s.r0);
      if (near_big) {  // leave it NaN: mark it like a big void
        for (int r = s.r0; r <= s.r1; ++r)
          for (int c = s.c0; c <= s.c1; ++c) {
            const size_t k = static_cast<size_t>(r) * w + c;
            if (state[k] == 1) state[k] = 2;
          }
      } else {
        fill = {std::min(fill.c0, s.c0), std::max(fill.c1, s.c1), std::min(fill.r0, s.r0), std::max(fill.r1, s.r1)};
      }
    }
    if (fill.c1 >= 0) {
      // Work on the holes' bounding box plus the search distance. Big voids
      // and uncovered posts get a placeholder value there: no hole is within
      // reach of them.
      const int c0 = std::max(0, fill.c0 - m), c1 = std::min(w - 1, fill.c1 + m);
      const int r0 = std::max(0, fill.r0 - m), r1 = std::min(h - 1, fill.r1 + m);
      const int ww = c1 - c0 + 1, wh = r1 - r0 + 1;
      std::vector<float> work(static_cast<size_t>(ww) * wh);
      for (int r = 0; r < wh; ++r)
        for (int c = 0; c < ww; ++c) {
          const size_t k = static_cast<size_t>(r + r0) * w + (c + c0);
          const bool placeholder = state[k] == 2 || (!covered[k] && buf[k] == kVoidSentinel);
          work[static_cast<size_t>(r) * ww + c] = placeholder ? 0.0f : buf[k];
        }
      GDALDriverH mem = GDALGetDriverByName("MEM");
      GDALDatasetH ds = GDALCreate(mem, "", ww, wh, 1, GDT_Float32, nullptr);
      GDALRasterBandH band = GDALGetRasterBand(ds, 1);
      GDALSetRasterNoDataValue(band, kVoidSentinel);
      CPLErr err = GDALRasterIO(band, GF_Write, 0, 0, ww, wh, work.data(), ww, wh, GDT_Float32, 0, 0);
      if (err == CE_None) err = GDALFillNodata(band, nullptr, kMaxVoidFillPx, 0, 0, nullptr, nullptr, nullptr);
      if (err == CE_None) err = GDALRasterIO(band, GF_Read, 0, 0, ww, wh, work.data(), ww, wh, GDT_Float32, 0, 0);
      GDALClose(ds);
      if (err != CE_None) throw IoError("dem: cannot fill voids of " + what + ": " + LastGdalMessage());
      for (int r = 0; r < wh; ++r)
        for (int c = 0; c < ww; ++c) {
          const size_t k = static_cast<size_t>(r + r0) * w + (c + c0);
          if (state[k] == 1) buf[k] = work[static_cast<size_t>(r) * ww + c];
        }
    }
  }
  for (size_t i = 0; i < buf.size(); ++i) {
    if (buf[i] == kVoidSentinel || !covered[i]) buf[i] = NAN;
  }
}

bool SameLattice(const Source& a, const Source& b) {
  auto close = [](double x, double y) { return std::abs(x - y) <= 1e-6 * std::abs(x); };
  if (!a.separable || !b.separable || !close(a.gt[1], b.gt[1]) || !close(a.gt[5], b.gt[5])) return false;
  const double fc = (b.gt[0] - a.gt[0]) / a.gt[1], fr = (b.gt[3] - a.gt[3]) / a.gt[5];
  return std::abs(fc - std::round(fc)) < 1e-3 && std::abs(fr - std::round(fr)) < 1e-3;
}

}  // namespace

struct Terrain::Impl {
  std::vector<Source> sources;
  std::vector<std::string> paths;
};

Terrain::Terrain(const std::vector<std::string>& paths) : impl_(std::make_unique<Impl>()) {
  if (paths.empty()) throw InvalidArgument("dem: no DEM file given");
  EnsureGdalRegistered();
  impl_->paths = paths;
  for (const auto& p : paths) impl_->sources.push_back(OpenSource(p));
}
Terrain::~Terrain() = default;
Terrain::Terrain(Terrain&&) noexcept = default;
Terrain& Terrain::operator=(Terrain&&) noexcept = default;

const std::vector<std::string>& Terrain::paths() const { return impl_->paths; }

bool Terrain::Covers(double lat_deg, double lon_deg) const {
  for (const Source& s : impl_->sources) {
    const auto px = PixelOfLatLon(s, lat_deg, lon_deg);
    if (!px) continue;
    const auto [col, row] = *px;
    if (col >= -1e-9 && row >= -1e-9 && col <= s.width - 1 + 1e-9 && row <= s.height - 1 + 1e-9) return true;
  }
  return false;
}

GeodeticPoint Terrain::CenterOf(size_t i) const {
  HR_CHECK(i < impl_->sources.size()) << "file index " << i;
  const Source& s = impl_->sources[i];
  double x, y, z = 0;
  GeoOfPixel(s, (s.width - 1) / 2, (s.height - 1) / 2, x, y);
  if (!s.separable) OCTTransform(static_cast<OGRCoordinateTransformationH>(s.to_wgs84.get()), 1, &x, &y, &z);
  return {y, x, 0.0};
}

GeoBox Terrain::ExtentOf(size_t i) const {
  HR_CHECK(i < impl_->sources.size()) << "file index " << i;
  const Source& s = impl_->sources[i];
  GeoBox b{INFINITY, -INFINITY, INFINITY, -INFINITY};
  constexpr int kSteps = 8;
  for (int k = 0; k <= kSteps; ++k)
    for (int side = 0; side < 4; ++side) {
      const double t = static_cast<double>(k) / kSteps;
      const double col = side < 2 ? t * (s.width - 1) : (side == 2 ? 0 : s.width - 1);
      const double row = side < 2 ? (side == 0 ? 0 : s.height - 1) : t * (s.height - 1);
      double x, y, z = 0;
      GeoOfPixel(s, col, row, x, y);
      if (!s.separable && !OCTTransform(static_cast<OGRCoordinateTransformationH>(s.to_wgs84.get()), 1, &x, &y, &z))
        continue;
      b.south = std::min(b.south, y), b.north = std::max(b.north, y);
      b.west = std::min(b.west, x), b.east = std::max(b.east, x);
    }
  return b;
}

std::vector<std::string> Terrain::SourceFilesOf(size_t i) const {
  HR_CHECK(i < impl_->sources.size()) << "file index " << i;
  std::vector<std::string> out;
  char** files = GDALGetFileList(static_cast<GDALDatasetH>(impl_->sources[i].dataset.get()));
  for (char** f = files; f && *f; ++f) out.emplace_back(*f);
  CSLDestroy(files);
  return out;
}

void AddSeaLevel(TerrainWindow& window, const GeodeticPoint& center, double radius_m) {
  // A flat surface: 0.005 deg posts (about 500 m) are exact under bilinear
  // interpolation and cheap to sweep.
  const double spacing = 0.005;
  const double dlat = radius_m / 111'000.0 + 2 * spacing;
  const double dlon = std::min(180.0, dlat / std::max(0.01, std::cos(DegToRad(center.lat_deg))));
  DemGrid g;
  g.separable = true;
  g.lat0_deg = std::min(90.0, center.lat_deg + dlat);
  g.dlat_deg = -spacing;
  g.lon0_deg = center.lon_deg - dlon;
  g.dlon_deg = spacing;
  g.height = static_cast<int>(std::ceil((g.lat0_deg - std::max(-90.0, center.lat_deg - dlat)) / spacing)) + 1;
  g.width = static_cast<int>(std::ceil(2 * dlon / spacing)) + 1;
  g.height_m.assign(static_cast<size_t>(g.width) * g.height, 0.0f);
  g.source = "sea level";
  g.IndexBlocks();
  window.grids.push_back(std::move(g));
}

namespace {

// Transforms n points (x, y) in place from the file's CRS to WGS84 (lon, lat).
void ToWgs84(const Source& a, std::vector<double>& x, std::vector<double>& y) {
  std::vector<double> z(x.size(), 0.0);
  if (!OCTTransform(static_cast<OGRCoordinateTransformationH>(a.to_wgs84.get()), static_cast<int>(x.size()), x.data(),
                    y.data(), z.data()))
    throw IoError("dem: cannot transform the posts of " + Quote(a.path) + " to WGS84: " + LastGdalMessage());
}

// The WGS84 position of every post of a projected grid. A projection is
// smooth over a few posts: the posts of a lattice every kLatticeStep posts
// are transformed exactly and the others interpolated bilinearly (longitudes
// unwrapped around each cell), which is checked at the centres of a sample
// of cells against the exact transform; beyond kLatticeTolDeg (~0.1 m, a
// thousandth of a post) every post is transformed. PROJ costs ~0.3 us a
// point: 120 ms for a 640 x 590 window, ~2 ms for the lattice (worst cell
// of dem_Columbia.tif, transverse Mercator 60 km off its meridian: 2 cm).
void PostPositions(const Source& a, const PixelWindow& w, DemGrid& g) {
  constexpr int kLatticeStep = 8;
  constexpr double kLatticeTolDeg = 1e-6;
  const int W = g.width, H = g.height;
  g.lon_deg.resize(static_cast<size_t>(W) * H);
  g.lat_deg.resize(g.lon_deg.size());
  auto exact_all = [&] {
    for (int r = 0; r < H; ++r)
      for (int c = 0; c < W; ++c) {
        const size_t k = static_cast<size_t>(r) * W + c;
        GeoOfPixel(a, w.c0 + c, w.r0 + r, g.lon_deg[k], g.lat_deg[k]);
      }
    ToWgs84(a, g.lon_deg, g.lat_deg);
  };
  if (W < 2 * kLatticeStep || H < 2 * kLatticeStep) return exact_all();
  // Lattice columns and rows: every kLatticeStep-th, and the last.
  std::vector<int> cols, rows;
  for (int c = 0; c < W - 1; c += kLatticeStep) cols.push_back(c);
  cols.push_back(W - 1);
  for (int r = 0; r < H - 1; r += kLatticeStep) rows.push_back(r);
  rows.push_back(H - 1);
  const int nc = static_cast<int>(cols.size()), nr = static_cast<int>(rows.size());
  std::vector<double> lx(static_cast<size_t>(nc) * nr), ly(lx.size());
  for (int j = 0; j < nr; ++j)
    for (int i = 0; i < nc; ++i) GeoOfPixel(a, w.c0 + cols[i], w.r0 + rows[j], lx[j * nc + i], ly[j * nc + i]);
  ToWgs84(a, lx, ly);
  // Bilinear within each lattice cell, longitudes relative to its corner.
  auto interpolate = [&](int i, int j, double fc, double fr, double& lon, double& lat) {
    const size_t k00 = static_cast<size_t>(j) * nc + i, k10 = k00 + 1, k01 = k00 + nc, k11 = k01 + 1;
    const double l0 = lx[k00];
    const double d10 = AngDiffDeg(lx[k10], l0), d01 = AngDiffDeg(lx[k01], l0), d11 = AngDiffDeg(lx[k11], l0);
    lon = l0 + (1 - fr) * fc * d10 + fr * ((1 - fc) * d01 + fc * d11);
    lat = (1 - fr) * ((1 - fc) * ly[k00] + fc * ly[k10]) + fr * ((1 - fc) * ly[k01] + fc * ly[k11]);
  };
  // Check: the centres of a sample of cells, exactly and interpolated.
  std::vector<double> cx, cy;
  std::vector<std::pair<int, int>> cells;
  for (int j = 0; j + 1 < nr; j += std::max(1, (nr - 1) / 6))
    for (int i = 0; i + 1 < nc; i += std::max(1, (nc - 1) / 6)) {
      cells.push_back({i, j});
      double px, py;
      GeoOfPixel(a, w.c0 + 0.5 * (cols[i] + cols[i + 1]), w.r0 + 0.5 * (rows[j] + rows[j + 1]), px, py);
      cx.push_back(px), cy.push_back(py);
    }
  ToWgs84(a, cx, cy);
  for (size_t t = 0; t < cells.size(); ++t) {
    double lon, lat;
    interpolate(cells[t].first, cells[t].second, 0.5, 0.5, lon, lat);
    if (!(std::abs(AngDiffDeg(lon, cx[t])) <= kLatticeTolDeg && std::abs(lat - cy[t]) <= kLatticeTolDeg))
      return exact_all();
  }
  for (int j = 0; j + 1 < nr; ++j)
    for (int r = rows[j]; r <= rows[j + 1]; ++r)
      for (int i = 0; i + 1 < nc; ++i)
        for (int c = cols[i]; c <= cols[i + 1]; ++c) {
          const size_t k = static_cast<size_t>(r) * W + c;
          interpolate(i, j, static_cast<double>(c - cols[i]) / (cols[i + 1] - cols[i]),
                      static_cast<double>(r - rows[j]) / (rows[j + 1] - rows[j]), g.lon_deg[k], g.lat_deg[k]);
        }
}

}  // namespace

TerrainWindow Terrain::ReadWindow(const GeodeticPoint& center, double radius_m) const {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    std::ostringstream m;
    m << "dem: window radius " << radius_m << " m must be positive and finite";
    throw InvalidArgument(m.str());
  }
  if (!Covers(center.lat_deg, center.lon_deg)) {
    std::ostringstream m;
    m.precision(8);
    m << "observer (" << center.lat_deg << ", " << center.lon_deg << ") is outside every DEM";
    for (const auto& p : impl_->paths) m << " " << Quote(p);
    throw InvalidArgument(m.str());
  }
  const auto& sources = impl_->sources;
  std::vector<PixelWindow> windows;
  for (const Source& s : sources) windows.push_back(WindowOf(s, center, radius_m));

  TerrainWindow out;
  // Bytes per post while a grid is built: height, void-fill state and
  // scratch; projected grids also hold each post's latitude and longitude.
  size_t bytes = 0;
  const auto reserve = [&](size_t posts, bool separable) {
    bytes += posts * (separable ? 10 : 30);
    if (bytes > max_window_bytes_) {
      std::ostringstream m;
      m.precision(6);
      m << "dem: the window within " << radius_m / 1000.0 << " km of (" << center.lat_deg << ", " << center.lon_deg
        << ") needs " << bytes / (1 << 20) << " MB (" << posts / 1'000'000.0 << " million posts in one grid), more than "
        << max_window_bytes_ / (1 << 20) << " MB allowed (--max-dem-mb): give a smaller --max-distance or a coarser DEM";
      throw InvalidArgument(m.str());
    }
  };
  std::vector<bool> done(sources.size(), false);
  for (size_t i = 0; i < sources.size(); ++i) {
    if (done[i] || windows[i].empty()) continue;
    const Source& a = sources[i];
    if (a.separable) {
      // Mosaic every source on a's lattice: union window in a's pixel frame.
      std::vector<size_t> group;
      double c0 = 1e300, r0 = 1e300, c1 = -1e300, r1 = -1e300;
      for (size_t j = i; j < sources.size(); ++j) {
        if (done[j] || windows[j].empty() || !SameLattice(a, sources[j])) continue;
        const Source& b = sources[j];
        const double oc = std::round((b.gt[0] - a.gt[0]) / a.gt[1]), orow = std::round((b.gt[3] - a.gt[3]) / a.gt[5]);
        c0 = std::min(c0, windows[j].c0 + oc), c1 = std::max(c1, windows[j].c1 + oc);
        r0 = std::min(r0, windows[j].r0 + orow), r1 = std::max(r1, windows[j].r1 + orow);
        group.push_back(j);
        done[j] = true;
      }
      DemGrid g;
      reserve(static_cast<size_t>((c1 - c0 + 1) * (r1 - r0 + 1)), true);  // before any int conversion
      g.width = static_cast<int>(c1 - c0 + 1), g.height = static_cast<int>(r1 - r0 + 1);
      g.separable = true;
      g.dlon_deg = a.gt[1], g.dlat_deg = a.gt[5];
      g.lon0_deg = a.gt[0] + (c0 + 0.5) * a.gt[1];
      g.lat0_deg = a.gt[3] + (r0 + 0.5) * a.gt[5];
      std::vector<float> buf(static_cast<size_t>(g.width) * g.height, kVoidSentinel);
      std::vector<uint8_t> covered(buf.size(), 0);
      std::vector<float> part;
      for (size_t j : group) {
        const Source& b = sources[j];
        const PixelWindow& w = windows[j];
        const int oc = static_cast<int>(std::round((b.gt[0] - a.gt[0]) / a.gt[1]) + w.c0 - c0);
        const int orow = static_cast<int>(std::round((b.gt[3] - a.gt[3]) / a.gt[5]) + w.r0 - r0);
        float* dst = buf.data() + static_cast<size_t>(orow) * g.width + oc;
        if (j == group.front()) {
          ReadPosts(b, w, dst, g.width);  // straight into the mosaic
        } else {
          // Tiles share edge posts: keep what is there unless it is void.
          part.resize(static_cast<size_t>(w.w()) * w.h());
          ReadPosts(b, w, part.data(), w.w());
          for (int r = 0; r < w.h(); ++r)
            for (int c = 0; c < w.w(); ++c) {
              float& v = dst[static_cast<size_t>(r) * g.width + c];
              if (v == kVoidSentinel) v = part[static_cast<size_t>(r) * w.w() + c];
            }
        }
        for (int r = 0; r < w.h(); ++r)
          std::fill_n(covered.begin() + static_cast<long>(r + orow) * g.width + oc, w.w(), uint8_t{1});
        g.source += (g.source.empty() ? "" : "+") + b.path;
      }
      FillVoids(buf, covered, g.width, g.height, Quote(g.source));
      g.height_m = std::move(buf);
      // Longitudes continuous from the observer's side of the antimeridian.
      g.lon0_deg += std::round((center.lon_deg - (g.lon0_deg + g.dlon_deg * g.width / 2)) / 360.0) * 360.0;
      g.IndexBlocks();
      out.grids.push_back(std::move(g));
    } else {
      done[i] = true;
      const PixelWindow& w = windows[i];
      DemGrid g;
      g.width = w.w(), g.height = w.h();
      reserve(static_cast<size_t>(g.width) * g.height, false);
      g.separable = false;
      g.source = a.path;
      std::vector<float> buf(static_cast<size_t>(w.w()) * w.h());
      ReadPosts(a, w, buf.data(), w.w());
      FillVoids(buf, std::vector<uint8_t>(buf.size(), 1), g.width, g.height, Quote(a.path));
      g.height_m = std::move(buf);
      PostPositions(a, w, g);
      g.IndexPositions();
      g.IndexBlocks();
      out.grids.push_back(std::move(g));
    }
  }
  bool any = false;
  for (const DemGrid& g : out.grids)
    for (float v : g.height_m) any = any || std::isfinite(v);
  if (!any) {
    std::ostringstream m;
    m << "dem: no elevation data (all voids) within " << radius_m / 1000.0 << " km of (" << center.lat_deg << ", "
      << center.lon_deg << ")";
    throw InvalidArgument(m.str());
  }
  return out;
}

std::optional<double> TerrainWindow::HeightAt(double lat_deg, double lon_deg) const {
  for (const DemGrid& g : grids) {
    if (auto h = g.HeightAt(lat_deg, lon_deg)) return h;
  }
  return std::nullopt;
}

std::optional<TerrainWindow> WithPostTrig(const TerrainWindow& window, size_t max_posts) {
  size_t posts = 0;
  bool projected = false;
  for (const DemGrid& g : window.grids) {
    posts += g.height_m.size();
    projected = projected || (!g.separable && g.post_trig.empty());
  }
  if (!projected || posts > max_posts) return std::nullopt;
  TerrainWindow out = window;
  for (DemGrid& g : out.grids)
    if (!g.separable && g.post_trig.empty()) g.IndexTrig();
  return out;
}

}  // namespace horizonreg
