// SPDX-License-Identifier: MIT
// Sensor readings that come with a photo or frame: compass, inclinometer
// and GPS (DESIGN.md "Sensor readings"), from a JSON file or the photo's EXIF.
#pragma once

#include <optional>
#include <string>

namespace horizonreg {

struct SensorReading {
  std::optional<double> compass_deg;    // azimuth of the optical axis, clockwise from (true) north, degrees
  std::optional<double> pitch_deg;      // inclinometer pitch, degrees, up positive
  std::optional<double> roll_deg;       // inclinometer roll, degrees, right side down positive
  std::optional<double> lat_deg, lon_deg;
  std::optional<double> alt_m;          // GPS altitude above mean sea level, metres
  std::optional<double> agl_m;          // height above ground, metres
  std::optional<double> focal_35mm;     // EXIF FocalLengthIn35mmFilm, millimetres
};

// Parses one reading from JSON text: fields compass_yaw_deg,
// inclinometer_pitch_deg, inclinometer_roll_deg, lat, lon, alt_m, agl_m; any
// may be absent or null. Throws InvalidArgument naming `source` and the field
// for a non-number or an out-of-range value (|pitch| > 90, |lat| > 90, ...).
SensorReading ParseSensorJson(const std::string& text, const std::string& source);

// Reads a sensor JSON file. Throws IoError if it cannot be read.
SensorReading ReadSensorJson(const std::string& path);

// What the photo's EXIF says (exiv2): GPS position and altitude,
// GPSImgDirection as the compass (only when its reference is true north, 'T',
// or absent), FocalLengthIn35mmFilm. Fields the photo lacks stay empty; a
// photo without EXIF gives an empty reading. Never throws for missing or
// malformed metadata. Thread-safe.
SensorReading ReadExif(const std::string& image_path);

// Horizontal opening angle (degrees) of a width x height image taken with a
// 35 mm-equivalent focal length (CIPA: the equivalence holds on the diagonal,
// 43.27 mm for full frame).
double HfovFromFocal35mm(double focal_35mm, int width, int height);

}  // namespace horizonreg
