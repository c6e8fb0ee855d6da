// SPDX-License-Identifier: MIT
#include "sensors/sensors.h"

#include <cmath>
#include <exiv2/exiv2.hpp>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {

namespace {

std::optional<double> Field(const nlohmann::json& j, const char* name, const std::string& source, double lo,
                            double hi) {
  if (!j.contains(name) || j[name].is_null()) return std::nullopt;
  if (!j[name].is_number())
    throw InvalidArgument("sensors: '" + source + "': field " + name + " is not a number");
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
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InvalidArgument("sensors: '" + source + "' is not valid JSON (" + e.what() + ")");
  }
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

SensorReading ReadSensorJson(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw IoError("sensors: cannot open '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return ParseSensorJson(ss.str(), path);
}

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
    const auto f35 = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalLengthIn35mmFilm"));
    if (f35 != exif.end() && f35->count() > 0 && f35->toLong() > 0) r.focal_35mm = static_cast<double>(f35->toLong());
  } catch (const Exiv2::Error&) {
    return SensorReading{};  // no usable metadata: the caller decides what is missing
  }
  return r;
}

double HfovFromFocal35mm(double focal_35mm, int width, int height) {
  const double half_diag = 0.5 * std::hypot(36.0, 24.0);
  const double tan_half_diag = half_diag / focal_35mm;
  return RadToDeg(2.0 * std::atan(tan_half_diag * width / std::hypot(width, height)));
}

}  // namespace horizonreg
