// SPDX-License-Identifier: MIT
// Sensor readings that come with a photo or frame: compass, inclinometer
// and GPS (DESIGN.md "Sensor readings"), from a JSON file or the photo's EXIF.
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace horizonreg {

struct SensorReading {
  std::optional<double> compass_deg;  // azimuth of the optical axis, clockwise from (true) north, degrees
  std::optional<double> pitch_deg;    // inclinometer pitch, degrees, up positive
  std::optional<double> roll_deg;     // inclinometer roll, degrees, right side down positive
  std::optional<double> lat_deg, lon_deg;
  std::optional<double> alt_m;       // GPS altitude above mean sea level, metres
  std::optional<double> agl_m;       // height above ground, metres
  std::optional<double> focal_35mm;  // EXIF FocalLengthIn35mmFilm, millimetres (or as below)
  // Set when focal_35mm is EXIF FocalLength times the body's crop factor
  // (camera_db.h), the photo giving no 35 mm equivalent of its own.
  bool focal_35mm_from_crop_factor = false;
  // EXIF PixelXDimension x PixelYDimension: the size the camera (or the last
  // program that rewrote the file) recorded; a photo cropped since shows
  // another shape than its pixels.
  std::optional<int> recorded_width_px, recorded_height_px;
  // EXIF Orientation 5-8: the pixels are stored turned a quarter, and the
  // decoded photo (turned upright) has the recorded size the other way round.
  bool turned = false;
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
// or absent), FocalLengthIn35mmFilm (else FocalLength times the crop factor
// of the body its Make and Model name, when lensfun knows it). Fields the
// photo lacks stay empty; a photo without EXIF gives an empty reading. Never throws for missing or
// malformed metadata. Thread-safe.
SensorReading ReadExif(const std::string& image_path);

// Horizontal opening angle (degrees) of a width x height image taken with a
// 35 mm-equivalent focal length (CIPA: the equivalence holds on the diagonal,
// 43.27 mm for full frame).
double HfovFromFocal35mm(double focal_35mm, int width, int height);

// The frame a 35 mm-equivalent focal length refers to, in a width x height
// image's pixels. When the recorded EXIF size (recorded_width_px x
// recorded_height_px, the other way round when `turned`) has the image's
// shape or is absent, the image itself. When its shape differs by
// more than 1.5%, the photo was cropped after it was taken (a photographer's
// or a web page's framing: the diagonal the equivalence holds on is the
// camera's, not the crop's): the recorded size scaled so that the side kept
// most is whole (a crop of one side is then exact; a crop of both still
// reads the opening angle too wide by the other side's crop).
struct Frame35mm {
  double width = 0.0, height = 0.0;
  bool cropped = false;
};
Frame35mm FrameOf(int width, int height, std::optional<int> recorded_width_px,
                  std::optional<int> recorded_height_px, bool turned = false);

// The opening angle of the image over its frame (FrameOf).
double HfovFromFocal35mm(double focal_35mm, int width, const Frame35mm& frame);

// One row of a per-frame sensor log.
struct SensorLogEntry {
  std::optional<int> frame;      // frame number (0-based), when the log has a `frame` column
  std::optional<double> time_s;  // seconds, when it has a `time_s` column
  SensorReading reading;
};

struct SensorLog {
  std::vector<SensorLogEntry> entries;  // in file order
  std::vector<std::string> warnings;    // one line per skipped row (garbage, NaN, missing fields)
  // The reading of a frame: the row with that frame number, else the row
  // nearest in time (frame / fps) within half a frame; nullopt if none.
  std::optional<SensorReading> ForFrame(int frame, double fps) const;
};

// Reads a per-frame log: CSV with a header naming `frame` and/or `time_s`
// and any of compass_yaw_deg, inclinometer_pitch_deg, inclinometer_roll_deg
// (DESIGN.md), or a JSON array of such objects. Rows that cannot be parsed,
// hold NaN or out-of-range values are skipped with a warning. Throws IoError
// if the file cannot be read, InvalidArgument naming the file if it has
// neither a frame nor a time column or no usable row at all.
// Bounds: a log of at most kMaxSensorLogBytes and kMaxSensorLogRows rows
// (InvalidArgument beyond, before memory runs out); at most kMaxSensorLogWarnings
// warnings are kept (and a last one counting the rest).
inline constexpr size_t kMaxSensorLogBytes = size_t{64} << 20;
inline constexpr size_t kMaxSensorLogRows = 1'000'000;  // 9 hours at 30 fps
inline constexpr size_t kMaxSensorLogWarnings = 100;
SensorLog ReadSensorLog(const std::string& path);

// Offsets that turn raw compass/inclinometer readings into the pose vision
// measured: compass = offset + drift * (t - t0) (a magnetometer's bias
// wanders slowly), pitch and roll constant offsets.
struct SensorCalibration {
  double compass_offset_deg = 0.0, compass_drift_deg_per_s = 0.0, t0_s = 0.0;
  double pitch_offset_deg = 0.0, roll_offset_deg = 0.0;
  int samples = 0;                                                        // visual poses used
  double compass_rms_deg = NAN, pitch_rms_deg = NAN, roll_rms_deg = NAN;  // residuals after calibration
  // A reading with the offsets applied (fields absent in `raw` stay absent).
  SensorReading Apply(const SensorReading& raw, double time_s) const;
  void Save(const std::string& path) const;                // JSON; throws IoError
  static SensorCalibration Load(const std::string& path);  // throws IoError / InvalidArgument
};

// Collects (raw reading, visual pose) pairs and fits the calibration: least
// squares, then again without pairs more than 3 robust sigmas off. The
// compass drift is fitted only over >= 2 s with >= 10 pairs. Not thread-safe.
class SensorCalibrator {
 public:
  void Add(double time_s, const SensorReading& raw, double azimuth_deg, double pitch_deg, double roll_deg);
  int size() const { return static_cast<int>(pairs_.size()); }
  std::optional<SensorCalibration> Estimate() const;  // nullopt without any pair

 private:
  struct Pair {
    double t;
    SensorReading raw;
    double az, pitch, roll;
  };
  std::vector<Pair> pairs_;
};

}  // namespace horizonreg
