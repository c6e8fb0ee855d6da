// SPDX-License-Identifier: MIT
// horizonreg._core: pybind11 bindings of the pipeline and the stage
// functions. Images are numpy uint8 arrays (H, W, 3) BGR, as OpenCV's Python
// module uses, or (H, W) grey; results are plain Python objects (the same
// JSON as the command line, as dicts) and numpy arrays; errors are Python
// exceptions with the command line's messages (ValueError for bad input,
// OSError for unreadable files, RuntimeError for internal failures).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <thread>

#include "dem/terrain.h"
#include "dem/tiles.h"
#include "horizon/horizon.h"
#include "overlay/overlay.h"
#include "pipeline/batch.h"
#include "pipeline/camera_file.h"
#include "pipeline/image_io.h"
#include "pipeline/position.h"
#include "pipeline/register_photo.h"
#include "pipeline/report.h"
#include "pipeline/site.h"
#include "sensors/sensors.h"
#include "skyline/skyline.h"
#include "util/errors.h"
#include "util/thread_pool.h"

namespace py = pybind11;
using namespace horizonreg;

namespace {

py::object ToPy(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }
nlohmann::json FromPy(const py::handle& o) {
  return nlohmann::json::parse(py::module_::import("json").attr("dumps")(o).cast<std::string>());
}

// A numpy uint8 image as a cv::Mat sharing its memory (valid while `array` lives).
cv::Mat MatOf(const py::array& array) {
  if (!py::isinstance<py::array_t<uint8_t>>(array))
    throw InvalidArgument("image: expected a numpy uint8 array, (H, W, 3) BGR or (H, W) grey");
  const py::array_t<uint8_t, py::array::c_style> a = py::array_t<uint8_t, py::array::c_style>::ensure(array);
  if (!a) throw InvalidArgument("image: cannot read the array");
  if (a.ndim() == 2) return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1, const_cast<uint8_t*>(a.data()));
  if (a.ndim() == 3 && a.shape(2) == 3)
    return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC3, const_cast<uint8_t*>(a.data())).clone();
  throw InvalidArgument("image: expected shape (H, W, 3) BGR or (H, W) grey, got " + std::to_string(a.ndim()) + " dimensions");
}

py::array ArrayOf(const cv::Mat& m) {
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  std::vector<py::ssize_t> shape = {c.rows, c.cols};
  if (c.channels() > 1) shape.push_back(c.channels());
  py::array_t<uint8_t> out(shape);
  std::memcpy(out.mutable_data(), c.data, c.total() * c.elemSize());
  return out;
}

py::array Doubles(const std::vector<double>& v) {
  py::array_t<double> out(static_cast<py::ssize_t>(v.size()));
  std::memcpy(out.mutable_data(), v.data(), v.size() * sizeof(double));
  return out;
}

py::dict HorizonDict(const HorizonProfile& p) {
  py::dict d;
  d["observer"] = py::dict(py::arg("lat") = p.observer.lat_deg, py::arg("lon") = p.observer.lon_deg,
                           py::arg("eye_height_m") = p.observer.height_m, py::arg("ground_height_m") = p.ground_height_m);
  d["step_deg"] = p.azimuth_step_deg;
  d["refraction"] = p.refraction;
  std::vector<double> az(p.size());
  for (int i = 0; i < p.size(); ++i) az[i] = p.AzimuthDeg(i);
  d["azimuth_deg"] = Doubles(az);
  d["elevation_deg"] = Doubles(p.elevation_deg);
  d["distance_m"] = Doubles(p.distance_m);
  d["lat"] = Doubles(p.lat_deg);
  d["lon"] = Doubles(p.lon_deg);
  d["height_m"] = Doubles(p.height_m);
  return d;
}

int Threads(int threads) { return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }

// A Site and the pool its work runs on (the pool outlives the site).
struct PySite {
  std::unique_ptr<ThreadPool> pool;
  std::unique_ptr<Site> site;
};

std::unique_ptr<PySite> MakeSite(double lat, double lon, const std::vector<std::string>& dem, const std::string& dem_dir,
                                 std::optional<double> agl, std::optional<double> alt, double max_distance, double step,
                                 double refraction, bool sea_level_fill, int threads) {
  SiteOptions o;
  o.agl_m = agl, o.alt_m = alt, o.max_distance_m = max_distance, o.azimuth_step_deg = step;
  o.refraction = refraction, o.sea_level_fill = sea_level_fill;
  o.Check();
  auto s = std::make_unique<PySite>();
  s->pool = std::make_unique<ThreadPool>(Threads(threads));
  const std::vector<std::string> files = DemFilesFor(dem, dem_dir, lat, lon, max_distance);
  py::gil_scoped_release release;
  s->site = std::make_unique<Site>(files, lat, lon, o, s->pool.get());
  return s;
}

py::object PyRegister(const py::object& image, const PySite& site, std::optional<double> hfov,
                    std::optional<std::pair<double, double>> hfov_range, const py::object& camera,
                    const py::object& sensors, std::optional<std::vector<double>> initial, bool pinhole,
                    std::optional<bool> exif, bool refine_position, std::optional<double> position_sigma,
                    bool trust_position, bool skyline) {
  const auto t0 = std::chrono::steady_clock::now();
  cv::Mat mat;
  PhotoOptions po;
  std::string name = "image";
  if (py::isinstance<py::str>(image)) {
    name = image.cast<std::string>();
    mat = ReadImage(name);
    if (exif.value_or(true)) po.exif = ReadExif(name);
  } else {
    mat = MatOf(image.cast<py::array>());
  }
  po.hfov_deg = hfov;
  po.hfov_range_deg = hfov_range;
  po.pinhole = pinhole;
  if (!camera.is_none())
    po.camera = py::isinstance<py::str>(camera) ? ReadCameraFile(camera.cast<std::string>(), mat.cols, mat.rows)
                                                : CameraFromJson(FromPy(camera), mat.cols, mat.rows, "camera");
  if (!sensors.is_none())
    po.sensors = py::isinstance<py::str>(sensors) ? ReadSensorJson(sensors.cast<std::string>())
                                                  : ParseSensorJson(FromPy(sensors).dump(), "sensors");
  if (initial) {
    if (initial->size() != 4) throw InvalidArgument("initial: expected (azimuth, pitch, roll, hfov) in degrees");
    char buf[160];
    std::snprintf(buf, sizeof(buf), "%.17g,%.17g,%.17g,%.17g", (*initial)[0], (*initial)[1], (*initial)[2], (*initial)[3]);
    po.initial = ParseInitialPose(buf, "initial");
  }
  po.position_sigma_m = position_sigma;
  if (trust_position) po.check_position.reset();
  if (refine_position) {
    po.refine_position = DefaultPositionOptions("arguments", false, position_sigma);
  }
  po.Check();
  nlohmann::json j;
  {
    py::gil_scoped_release release;
    const PhotoRegistration r = RegisterPhoto(*site.site, mat, po, site.pool.get());
    j = RegistrationReport(*site.site, r, "arguments",
                           std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (skyline) j["skyline"] = SkylineJson(RegisteredSkyline(*site.site, mat, r));
  }
  if (py::isinstance<py::str>(image)) j["image"] = name;
  return ToPy(j);
}

BatchOptions MakeBatchOptions(const std::vector<std::string>& dem, const std::string& dem_dir, std::optional<double> hfov,
                              std::optional<std::pair<double, double>> hfov_range, bool pinhole, bool exif, double step,
                              double refraction, double max_distance, bool sea_level_fill, bool refine_position,
                              std::optional<double> position_sigma, bool skylines, bool check_every_photo) {
  BatchOptions o;
  o.dem = dem;
  if (!dem_dir.empty()) {
    if (!dem.empty()) throw InvalidArgument("give dem files or dem_dir, not both");
    auto index = std::make_shared<DemTileIndex>(dem_dir);
    o.dem_for = [index](double lat, double lon, double d) { return index->TilesAround(lat, lon, d); };
  }
  o.site.azimuth_step_deg = step, o.site.refraction = refraction, o.site.max_distance_m = max_distance;
  o.site.sea_level_fill = sea_level_fill;
  o.photo.hfov_deg = hfov;
  o.photo.hfov_range_deg = hfov_range;
  o.photo.pinhole = pinhole;
  o.use_exif = exif;
  o.refine_position = refine_position;
  o.photo.position_sigma_m = position_sigma;
  o.skylines = skylines;
  o.vouch_stations = !check_every_photo;
  o.Check();
  return o;
}

py::list ItemsToPy(const std::vector<BatchItem>& items) {
  py::list out;
  for (const BatchItem& it : items) {
    py::dict d;
    d["image"] = it.image;
    d["image_path"] = it.image_path;
    for (auto [k, v] : {std::pair{"lat", it.lat}, {"lon", it.lon}, {"alt_m", it.alt_m}, {"agl_m", it.agl_m}, {"hfov_deg", it.hfov_deg}})
      d[k] = v ? py::object(py::float_(*v)) : py::object(py::none());
    d["camera"] = it.camera_path;
    d["sensors"] = it.sensors_path;
    d["station"] = it.station;
    d["initial"] = it.initial ? py::object(py::make_tuple(it.initial->azimuth_deg, it.initial->pitch_deg,
                                                           it.initial->roll_deg, it.initial->hfov_deg))
                              : py::object(py::none());
    out.append(d);
  }
  return out;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "horizonreg: camera orientation from terrain horizons (compiled part)";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InvalidArgument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const IoError& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    } catch (const Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });

  m.def("read_image", [](const std::string& path) { return ArrayOf(ReadImage(path)); }, py::arg("path"),
        "Decodes an image file to a uint8 (H, W, 3) BGR array (EXIF orientation applied).");

  m.def(
      "compute_horizon",
      [](double lat, double lon, const std::vector<std::string>& dem, const std::string& dem_dir,
         std::optional<double> agl, std::optional<double> alt, double step, double max_distance, double refraction,
         bool sea_level_fill, int threads) {
        HorizonOptions ho;
        ho.azimuth_step_deg = step, ho.max_distance_m = max_distance, ho.refraction = refraction;
        ho.num_threads = Threads(threads);
        ho.Check();
        const std::vector<std::string> files = DemFilesFor(dem, dem_dir, lat, lon, max_distance);
        HorizonProfile p;
        {
          py::gil_scoped_release release;
          const Terrain terrain(files);
          TerrainWindow w = terrain.ReadWindow({lat, lon, 0.0}, max_distance);
          if (sea_level_fill) AddSeaLevel(w, {lat, lon, 0.0}, max_distance);
          p = ComputeHorizon(w, ResolveObserver(w, lat, lon, agl, alt), ho);
        }
        return HorizonDict(p);
      },
      py::arg("lat"), py::arg("lon"), py::arg("dem") = std::vector<std::string>{}, py::arg("dem_dir") = "",
      py::arg("agl") = py::none(), py::arg("alt") = py::none(), py::arg("step") = 0.25,
      py::arg("max_distance") = 100'000.0, py::arg("refraction") = kDefaultRefraction,
      py::arg("sea_level_fill") = false, py::arg("threads") = 0,
      "The 360-degree horizon at (lat, lon): dict of numpy arrays (azimuth_deg, elevation_deg, distance_m, lat, "
      "lon, height_m) and the observer, as `horizonreg horizon --format json`.");

  m.def(
      "extract_skyline",
      [](const py::array& image, std::optional<double> roll_hint_deg) {
        const cv::Mat mat = MatOf(image);
        SkylineOptions o;
        o.roll_hint_deg = roll_hint_deg;
        o.Check();
        Skyline s;
        {
          py::gil_scoped_release release;
          s = ExtractSkyline(mat.channels() == 1 ? [&] { cv::Mat bgr; cv::Mat planes[3] = {mat, mat, mat}; cv::merge(planes, 3, bgr); return bgr; }() : mat, o);
        }
        py::dict d;
        d["width"] = s.width;
        d["height"] = s.height;
        d["y"] = Doubles(s.y);
        d["confidence"] = Doubles(s.confidence);
        return d;
      },
      py::arg("image"), py::arg("roll_hint_deg") = py::none(),
      "The sky/terrain boundary: dict with 'y' (one y per column, NaN where not visible) and 'confidence'.");

  py::class_<PySite>(m, "Site", "A camera position with its DEM window and registration horizon, built once.")
      .def(py::init(&MakeSite), py::arg("lat"), py::arg("lon"), py::arg("dem") = std::vector<std::string>{},
           py::arg("dem_dir") = "", py::arg("agl") = py::none(), py::arg("alt") = py::none(),
           py::arg("max_distance") = 100'000.0, py::arg("step") = kRegistrationStepDeg,
           py::arg("refraction") = kDefaultRefraction, py::arg("sea_level_fill") = false, py::arg("threads") = 0)
      .def_property_readonly("observer",
                             [](const PySite& s) {
                               const GeodeticPoint& o = s.site->observer();
                               return py::dict(py::arg("lat") = o.lat_deg, py::arg("lon") = o.lon_deg,
                                               py::arg("eye_height_m") = o.height_m);
                             })
      .def_property_readonly("horizon", [](const PySite& s) { return HorizonDict(s.site->horizon()); })
      .def_property_readonly("load_ms", [](const PySite& s) { return s.site->load_ms() + s.site->horizon_ms(); });

  m.def("register", &PyRegister, py::arg("image"), py::arg("site"), py::arg("hfov") = py::none(),
        py::arg("hfov_range") = py::none(), py::arg("camera") = py::none(), py::arg("sensors") = py::none(),
        py::arg("initial") = py::none(), py::arg("pinhole") = false, py::arg("exif") = py::none(),
        py::arg("refine_position") = false, py::arg("position_sigma") = py::none(), py::arg("trust_position") = false,
        py::arg("skyline") = false,
        "Registers a photo (numpy array or path) taken at `site`: the register JSON as a dict; with "
        "refine_position, also the site's latitude, longitude and eye height (the \"position\" block); "
        "trust_position (a surveyed camera, as register --trust-position) skips the position check and lets "
        "`initial` decide instead of only vetoing; skyline adds \"skyline\" (the skyline JSON, for a registered "
        "photo read again near the DEM horizon at its pose, as register --skyline-out).");

  m.def(
      "draw_overlay",
      [](const py::array& image, const PySite& site, const py::dict& pose, const std::string& landmarks) {
        const cv::Mat mat = MatOf(image);
        const nlohmann::json p = FromPy(pose);
        const auto number = [&](const char* k) {
          if (!p.contains(k) || !p[k].is_number()) throw InvalidArgument(std::string("pose: no number '") + k + "' (not registered?)");
          return p[k].get<double>();
        };
        const CameraPose cp{number("azimuth_deg"), number("pitch_deg"), number("roll_deg")};
        CameraIntrinsics k = p.contains("camera") && p["camera"].is_object() && p["camera"].contains("focal_px")
                                 ? CameraFromJson(p["camera"], mat.cols, mat.rows, "pose camera")
                                 : CameraIntrinsics::FromHfov(mat.cols, mat.rows, number("hfov_deg"));
        cv::Mat out;
        {
          py::gil_scoped_release release;
          OverlayOptions oo;
          oo.eye_height_m = site.site->EyeAboveGroundM();
          cv::Mat bgr = mat;
          if (mat.channels() == 1) {
            const cv::Mat planes[3] = {mat, mat, mat};
            cv::merge(planes, 3, bgr);
          }
          out = DrawOverlay(bgr, cp, k, {&site.site->horizon(), &site.site->ridges(), OverlayLandmarks(*site.site, landmarks)}, oo)
                    .image;
        }
        return ArrayOf(out);
      },
      py::arg("image"), py::arg("site"), py::arg("pose"), py::arg("landmarks") = "",
      "The AR overlay (DEM silhouette, ridges, landmarks, compass) drawn at `pose` (a register dict): a new BGR array.");

  m.def(
      "read_manifest",
      [](const std::string& path, const std::string& stations) {
        return ItemsToPy(ReadManifest(path, stations.empty() ? std::map<std::string, BatchStation>{} : ReadStations(stations)));
      },
      py::arg("path"), py::arg("stations") = "",
      "The photos of a batch manifest (CSV, JSON or a folder) as dicts, paths resolved (image_path).");

  m.def(
      "batch_rows",
      [](const py::list& rows, const std::string& base_dir, const std::vector<std::string>& dem,
         const std::string& dem_dir, std::optional<double> hfov, std::optional<std::pair<double, double>> hfov_range,
         bool pinhole, bool exif, double step, double refraction, double max_distance, bool sea_level_fill,
         bool refine_position, std::optional<double> position_sigma, bool skylines, bool check_every_photo,
         int threads) {
        const std::vector<BatchItem> items = ManifestFromJson(FromPy(rows), base_dir, "rows");
        const BatchOptions o =
            MakeBatchOptions(dem, dem_dir, hfov, hfov_range, pinhole, exif, step, refraction, max_distance, sea_level_fill,
                             refine_position, position_sigma, skylines, check_every_photo);
        std::vector<std::pair<size_t, nlohmann::json>> out;
        {
          py::gil_scoped_release release;
          ThreadPool pool(Threads(threads));
          std::mutex mu;
          RunBatch(items, o, pool, [&](const BatchResult& r) {
            std::lock_guard<std::mutex> lock(mu);
            out.emplace_back(static_cast<size_t>(r.item - items.data()), r.row);
          });
        }
        std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
        py::list result;
        for (auto& [i, row] : out) result.append(ToPy(row));
        return result;
      },
      py::arg("rows"), py::arg("base_dir") = ".", py::arg("dem") = std::vector<std::string>{}, py::arg("dem_dir") = "",
      py::arg("hfov") = py::none(), py::arg("hfov_range") = py::none(), py::arg("pinhole") = false,
      py::arg("exif") = true, py::arg("step") = kRegistrationStepDeg, py::arg("refraction") = kDefaultRefraction,
      py::arg("max_distance") = 100'000.0, py::arg("sea_level_fill") = false, py::arg("refine_position") = false,
      py::arg("position_sigma") = py::none(), py::arg("skylines") = false, py::arg("check_every_photo") = false,
      py::arg("threads") = 0,
      "Registers manifest rows (dicts with the manifest's columns) as `horizonreg batch` does: one row dict per "
      "photo, in the rows' order; skylines adds each row's \"skyline\" (as batch --skylines); check_every_photo "
      "runs the position check's wide look on every photo (as batch --check-every-photo).");
}
