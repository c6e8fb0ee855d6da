// SPDX-License-Identifier: MIT
#include "sensors/sensors.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <exiv2/exiv2.hpp>
#include <mutex>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sensors/camera_db.h"
#include "util/angles.h"
#include "util/errors.h"
#include "util/json.h"
#include "util/text.h"

namespace horizonreg {

namespace {

std::optional<double> Field(const nlohmann::json& j, const char* name, const std::string& source, double lo,
                            double hi) {
  if (!j.contains(name) || j[name].is_null()) return std::nullopt;
  if (!j[name].is_number()) throw InvalidArgument("sensors: '" + source + "': field " + name + " is not a number");
  const double v = j[name].get<double>();
  if (!(v >= lo && v <= hi)) {
    std::ostringstream m;
    m << "sensors: '" << source << "': " << name << " = " << v << " is outside [" << lo << ", " << hi << "]";
    throw InvalidArgument(m.str());
  }
  return v;
}

}  // namespace

SensorReading ParseSensorJson(const std::string& text, const std::string& source) {
  const nlohmann::json j = ParseJson(text, "sensors", source);
  if (!j.is_object()) throw InvalidArgument("sensors: '" + source + "' is not a JSON object");
  SensorReading r;
  r.compass_deg = Field(j, "compass_yaw_deg", source, -360.0, 720.0);
  if (r.compass_deg) r.compass_deg = WrapAzimuthDeg(*r.compass_deg);
  r.pitch_deg = Field(j, "inclinometer_pitch_deg", source, -90.0, 90.0);
  r.roll_deg = Field(j, "inclinometer_roll_deg", source, -180.0, 180.0);
  r.lat_deg = Field(j, "lat", source, -90.0, 90.0);
  r.lon_deg = Field(j, "lon", source, -180.0, 360.0);
  r.alt_m = Field(j, "alt_m", source, -500.0, 9000.0);
  r.agl_m = Field(j, "agl_m", source, 0.0, 10000.0);
  return r;
}

SensorReading ReadSensorJson(const std::string& path) { return ParseSensorJson(ReadTextFile(path, "sensors", size_t{16} << 20), path); }

namespace {

std::optional<double> Rational(const Exiv2::ExifData& exif, const char* key, long index = 0) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end() || it->count() <= index) return std::nullopt;
  const Exiv2::Rational r = it->toRational(index);
  if (r.second == 0) return std::nullopt;
  return static_cast<double>(r.first) / r.second;
}

std::optional<std::string> Text(const Exiv2::ExifData& exif, const char* key) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end()) return std::nullopt;
  return it->toString();
}

std::optional<double> Dms(const Exiv2::ExifData& exif, const char* key, const char* ref_key, char negative) {
  const auto d = Rational(exif, key, 0), m = Rational(exif, key, 1), s = Rational(exif, key, 2);
  if (!d || !m || !s) return std::nullopt;
  double v = *d + *m / 60.0 + *s / 3600.0;
  const auto ref = Text(exif, ref_key);
  if (ref && !ref->empty() && (*ref)[0] == negative) v = -v;
  return v;
}

}  // namespace

SensorReading ReadExif(const std::string& image_path) {
  // exiv2 writes its warnings (e.g. "IFD exceeds data buffer" on ordinary
  // Nikon JPEGs) to stderr itself; they never reach our user: its
  // process-wide log level is set to mute, once. A tag it could not read is
  // simply absent.
  static std::once_flag mute_exiv2;
  std::call_once(mute_exiv2, [] { Exiv2::LogMsg::setLevel(Exiv2::LogMsg::mute); });
  SensorReading r;
  try {
    auto image = Exiv2::ImageFactory::open(image_path);
    if (image.get() == nullptr) return r;
    image->readMetadata();
    const Exiv2::ExifData& exif = image->exifData();
    if (exif.empty()) return r;
    r.lat_deg = Dms(exif, "Exif.GPSInfo.GPSLatitude", "Exif.GPSInfo.GPSLatitudeRef", 'S');
    r.lon_deg = Dms(exif, "Exif.GPSInfo.GPSLongitude", "Exif.GPSInfo.GPSLongitudeRef", 'W');
    if (r.lat_deg && !(std::abs(*r.lat_deg) <= 90.0)) r.lat_deg.reset();
    if (r.lon_deg && !(std::abs(*r.lon_deg) <= 180.0)) r.lon_deg.reset();
    if (!r.lat_deg || !r.lon_deg) r.lat_deg.reset(), r.lon_deg.reset();
    r.alt_m = Rational(exif, "Exif.GPSInfo.GPSAltitude");
    const auto alt_ref = exif.findKey(Exiv2::ExifKey("Exif.GPSInfo.GPSAltitudeRef"));
    if (r.alt_m && alt_ref != exif.end() && alt_ref->count() > 0 && alt_ref->toLong() == 1) r.alt_m = -*r.alt_m;
    const auto dir = Rational(exif, "Exif.GPSInfo.GPSImgDirection");
    const auto dir_ref = Text(exif, "Exif.GPSInfo.GPSImgDirectionRef");
    if (dir && std::isfinite(*dir) && (!dir_ref || dir_ref->empty() || (*dir_ref)[0] == 'T'))
      r.compass_deg = WrapAzimuthDeg(*dir);
    for (const auto& [key, field] : {std::pair{"Exif.Photo.PixelXDimension", &r.recorded_width_px},
                                     std::pair{"Exif.Photo.PixelYDimension", &r.recorded_height_px}}) {
      const auto it = exif.findKey(Exiv2::ExifKey(key));
      if (it != exif.end() && it->count() > 0 && it->toLong() > 0 && it->toLong() < 1000000)
        *field = static_cast<int>(it->toLong());
    }
    if (const auto o = exif.findKey(Exiv2::ExifKey("Exif.Image.Orientation")); o != exif.end() && o->count() > 0)
      r.turned = o->toLong() >= 5 && o->toLong() <= 8;
    const auto f35 = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalLengthIn35mmFilm"));
    if (f35 != exif.end() && f35->count() > 0 && f35->toLong() > 0) {
      r.focal_35mm = static_cast<double>(f35->toLong());
    } else if (const auto f = Rational(exif, "Exif.Photo.FocalLength"); f && *f > 0.0 && *f < 5000.0) {
      // No 35 mm equivalent (Canon bodies write none): the lens's focal
      // length times the body's crop factor.
      const auto make = Text(exif, "Exif.Image.Make"), model = Text(exif, "Exif.Image.Model");
      if (make && model)
        if (const auto crop = CameraCropFactor(Trim(*make), Trim(*model))) {
          r.focal_35mm = *f * *crop;
          r.focal_35mm_from_crop_factor = true;
        }
    }
  } catch (const Exiv2::Error&) {
    return SensorReading{};  // no usable metadata: the caller decides what is missing
  }
  return r;
}

std::optional<SensorReading> SensorLog::ForFrame(int frame, double fps) const {
  for (const SensorLogEntry& e : entries)
    if (e.frame && *e.frame == frame) return e.reading;
  if (!(fps > 0)) return std::nullopt;
  const double t = frame / fps;
  const SensorLogEntry* best = nullptr;
  for (const SensorLogEntry& e : entries)
    if (e.time_s && std::abs(*e.time_s - t) <= 0.5 / fps &&
        (!best || std::abs(*e.time_s - t) < std::abs(*best->time_s - t)))
      best = &e;
  if (best) return best->reading;
  return std::nullopt;
}

SensorLog ReadSensorLog(const std::string& path) {
  const std::string text = ReadTextFile(path, "sensors", kMaxSensorLogBytes);
  SensorLog log;
  size_t skipped = 0;
  const auto warn = [&](std::string w) {
    if (log.warnings.size() < kMaxSensorLogWarnings) log.warnings.push_back(std::move(w));
    else ++skipped;
  };
  const auto add = [&](const SensorLogEntry& e) {
    if (log.entries.size() >= kMaxSensorLogRows)
      throw InvalidArgument("sensors: '" + path + "' has more than " + std::to_string(kMaxSensorLogRows) +
                            " rows; split the log");
    log.entries.push_back(e);
  };
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '[') {
    const nlohmann::json j = ParseJson(text, "sensors", path);
    for (size_t i = 0; i < j.size(); ++i) {
      try {
        if (!j[i].is_object()) throw InvalidArgument("not an object");
        SensorLogEntry e;
        e.reading = ParseSensorJson(j[i].dump(), path);
        if (j[i].contains("frame") && j[i]["frame"].is_number_integer()) {
          const int64_t frame = j[i]["frame"].get<int64_t>();
          if (frame < 0 || frame > std::numeric_limits<int>::max()) throw InvalidArgument("bad frame");
          e.frame = static_cast<int>(frame);
        }
        if (j[i].contains("time_s") && j[i]["time_s"].is_number()) e.time_s = j[i]["time_s"].get<double>();
        if (!e.frame && !e.time_s) throw InvalidArgument("no frame or time_s");
        add(e);
      } catch (const InvalidArgument& ex) {
        if (log.entries.size() >= kMaxSensorLogRows) throw;
        warn("sensors: '" + path + "' element " + std::to_string(i) + " skipped: " + ex.what());
      }
    }
  } else {
    std::istringstream lines(text);
    std::string line;
    std::getline(lines, line);
    auto header = SplitCsvLine(line);
    for (std::string& h : header) h.erase(std::remove_if(h.begin(), h.end(), ::isspace), h.end());
    auto col = [&](const char* name) {
      for (size_t i = 0; i < header.size(); ++i)
        if (header[i] == name) return static_cast<int>(i);
      return -1;
    };
    const int c_frame = col("frame"), c_time = col("time_s"), c_yaw = col("compass_yaw_deg"),
              c_pitch = col("inclinometer_pitch_deg"), c_roll = col("inclinometer_roll_deg");
    if (c_frame < 0 && c_time < 0)
      throw InvalidArgument("sensors: '" + path + "' has no `frame` or `time_s` column in its header");
    int number = 1;
    while (std::getline(lines, line)) {
      ++number;
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      const auto cells = SplitCsvLine(line);
      auto cell = [&](int c) -> std::optional<double> {
        if (c < 0) return std::nullopt;
        if (c >= static_cast<int>(cells.size())) return NAN;
        if (cells[c].find_first_not_of(" \t") == std::string::npos) return std::nullopt;
        return ParseDouble(cells[c]).value_or(NAN);
      };
      const auto frame = cell(c_frame), time = cell(c_time), yaw = cell(c_yaw), pitch = cell(c_pitch),
                 roll = cell(c_roll);
      std::string why;
      if ((frame && !(std::isfinite(*frame) && *frame >= 0 && *frame <= std::numeric_limits<int>::max() &&
                      *frame == std::floor(*frame))) ||
          (time && !std::isfinite(*time)) || (!frame && !time))
        why = "bad frame/time";
      else if (yaw && !(std::isfinite(*yaw) && std::abs(*yaw) <= 720))
        why = "bad compass_yaw_deg";
      else if (pitch && !(std::isfinite(*pitch) && std::abs(*pitch) <= 90))
        why = "bad inclinometer_pitch_deg";
      else if (roll && !(std::isfinite(*roll) && std::abs(*roll) <= 180))
        why = "bad inclinometer_roll_deg";
      if (!why.empty()) {
        warn("sensors: '" + path + "' line " + std::to_string(number) + " skipped: " + why);
        continue;
      }
      SensorLogEntry e;
      if (frame) e.frame = static_cast<int>(*frame);
      e.time_s = time;
      if (yaw) e.reading.compass_deg = WrapAzimuthDeg(*yaw);
      e.reading.pitch_deg = pitch;
      e.reading.roll_deg = roll;
      add(e);
    }
  }
  if (skipped > 0) log.warnings.push_back("sensors: '" + path + "': " + std::to_string(skipped) + " more rows skipped");
  if (log.entries.empty()) throw InvalidArgument("sensors: '" + path + "' has no usable reading");
  return log;
}

SensorReading SensorCalibration::Apply(const SensorReading& raw, double time_s) const {
  SensorReading r = raw;
  if (r.compass_deg)
    r.compass_deg = WrapAzimuthDeg(*r.compass_deg + compass_offset_deg + compass_drift_deg_per_s * (time_s - t0_s));
  if (r.pitch_deg) r.pitch_deg = *r.pitch_deg + pitch_offset_deg;
  if (r.roll_deg) r.roll_deg = *r.roll_deg + roll_offset_deg;
  return r;
}

void SensorCalibration::Save(const std::string& path) const {
  nlohmann::json j = {{"compass_offset_deg", compass_offset_deg},
                      {"compass_drift_deg_per_s", compass_drift_deg_per_s},
                      {"t0_s", t0_s},
                      {"pitch_offset_deg", pitch_offset_deg},
                      {"roll_offset_deg", roll_offset_deg},
                      {"samples", samples},
                      {"compass_rms_deg", std::isfinite(compass_rms_deg) ? nlohmann::json(compass_rms_deg) : nullptr},
                      {"pitch_rms_deg", std::isfinite(pitch_rms_deg) ? nlohmann::json(pitch_rms_deg) : nullptr},
                      {"roll_rms_deg", std::isfinite(roll_rms_deg) ? nlohmann::json(roll_rms_deg) : nullptr}};
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f || !(f << j.dump(1) << "\n")) throw IoError("sensors: cannot write '" + path + "'");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw IoError("sensors: cannot write '" + path + "'");
  }
}

SensorCalibration SensorCalibration::Load(const std::string& path) {
  const nlohmann::json j = ParseJson(ReadTextFile(path, "sensors: calibration", size_t{16} << 20), "sensors: calibration", path);
  SensorCalibration c;
  auto get = [&](const char* k, double& v) {
    if (!j.contains(k) || !j[k].is_number() || !std::isfinite(j[k].get<double>()))
      throw InvalidArgument("sensors: calibration '" + path + "' lacks a number '" + k + "'");
    v = j[k].get<double>();
  };
  get("compass_offset_deg", c.compass_offset_deg);
  get("compass_drift_deg_per_s", c.compass_drift_deg_per_s);
  get("t0_s", c.t0_s);
  get("pitch_offset_deg", c.pitch_offset_deg);
  get("roll_offset_deg", c.roll_offset_deg);
  c.samples = j.value("samples", 0);
  return c;
}

void SensorCalibrator::Add(double time_s, const SensorReading& raw, double azimuth_deg, double pitch_deg,
                           double roll_deg) {
  pairs_.push_back({time_s, raw, azimuth_deg, pitch_deg, roll_deg});
}

namespace {

// Robust straight line (or constant) fit of y against t: least squares, then
// again without points more than 3 robust sigmas off. Returns {a, b, rms}.
std::array<double, 3> RobustLine(const std::vector<double>& t, const std::vector<double>& y, bool with_slope,
                                 double t0) {
  std::vector<char> use(t.size(), 1);
  double a = 0, b = 0, rms = NAN;
  for (int pass = 0; pass < 2; ++pass) {
    double n = 0, st = 0, sy = 0, stt = 0, sty = 0;
    for (size_t i = 0; i < t.size(); ++i) {
      if (!use[i]) continue;
      const double x = t[i] - t0;
      n += 1, st += x, sy += y[i], stt += x * x, sty += x * y[i];
    }
    if (n == 0) break;
    const double det = n * stt - st * st;
    if (with_slope && det > 1e-9 * n * n) {
      b = (n * sty - st * sy) / det;
      a = (sy - b * st) / n;
    } else {
      b = 0, a = sy / n;
    }
    std::vector<double> res;
    for (size_t i = 0; i < t.size(); ++i)
      if (use[i]) res.push_back(std::abs(y[i] - a - b * (t[i] - t0)));
    std::vector<double> sorted = res;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double sigma = std::max(1.4826 * sorted[sorted.size() / 2], 1e-3);
    double ss = 0;
    for (double r : res) ss += r * r;
    rms = std::sqrt(ss / res.size());
    if (pass == 0)
      for (size_t i = 0; i < t.size(); ++i) use[i] = std::abs(y[i] - a - b * (t[i] - t0)) <= 3 * sigma;
  }
  return {a, b, rms};
}

}  // namespace

std::optional<SensorCalibration> SensorCalibrator::Estimate() const {
  if (pairs_.empty()) return std::nullopt;
  SensorCalibration c;
  c.samples = size();
  std::vector<double> tc, yc, tp, yp, tr, yr;
  double tmin = INFINITY, tmax = -INFINITY;
  for (const Pair& p : pairs_) {
    if (p.raw.compass_deg) tc.push_back(p.t), yc.push_back(AngDiffDeg(p.az, *p.raw.compass_deg));
    if (p.raw.pitch_deg) tp.push_back(p.t), yp.push_back(p.pitch - *p.raw.pitch_deg);
    if (p.raw.roll_deg) tr.push_back(p.t), yr.push_back(p.roll - *p.raw.roll_deg);
    tmin = std::min(tmin, p.t), tmax = std::max(tmax, p.t);
  }
  c.t0_s = tmin;
  if (!yc.empty()) {
    // Unwrap around the first difference so that 359 and 1 average to 0.
    for (double& v : yc) v = yc[0] + AngDiffDeg(v, yc[0]);
    const auto [a, b, rms] = RobustLine(tc, yc, tmax - tmin >= 2.0 && tc.size() >= 10, c.t0_s);
    c.compass_offset_deg = a, c.compass_drift_deg_per_s = b, c.compass_rms_deg = rms;
  }
  if (!yp.empty()) {
    const auto [a, b, rms] = RobustLine(tp, yp, false, c.t0_s);
    c.pitch_offset_deg = a, c.pitch_rms_deg = rms;
    (void)b;
  }
  if (!yr.empty()) {
    const auto [a, b, rms] = RobustLine(tr, yr, false, c.t0_s);
    c.roll_offset_deg = a, c.roll_rms_deg = rms;
    (void)b;
  }
  return c;
}

double HfovFromFocal35mm(double focal_35mm, int width, int height) {
  return HfovFromFocal35mm(focal_35mm, width, Frame35mm{static_cast<double>(width), static_cast<double>(height)});
}

Frame35mm FrameOf(int width, int height, std::optional<int> recorded_width_px, std::optional<int> recorded_height_px,
                  bool turned) {
  constexpr double kShapeTolerance = 0.015;  // rounding a resized photo's sides stays far below
  Frame35mm f{static_cast<double>(width), static_cast<double>(height), false};
  if (!recorded_width_px || !recorded_height_px || *recorded_width_px <= 0 || *recorded_height_px <= 0 ||
      width <= 0 || height <= 0)
    return f;
  double rw = *recorded_width_px, rh = *recorded_height_px;
  if (turned) std::swap(rw, rh);  // a portrait crop of a landscape photo is not turned
  if (std::abs((width / static_cast<double>(height)) / (rw / rh) - 1.0) <= kShapeTolerance) return f;
  const double scale = std::max(width / rw, height / rh);
  return Frame35mm{rw * scale, rh * scale, true};
}

double HfovFromFocal35mm(double focal_35mm, int width, const Frame35mm& frame) {
  const double half_diag = 0.5 * std::hypot(36.0, 24.0);
  const double tan_half_diag = half_diag / focal_35mm;
  return RadToDeg(2.0 * std::atan(tan_half_diag * width / std::hypot(frame.width, frame.height)));
}

}  // namespace horizonreg
