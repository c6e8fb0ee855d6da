// SPDX-License-Identifier: MIT
#include "sensors/sensors.h"

#include <gtest/gtest.h>

#include <exiv2/exiv2.hpp>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "sensors/camera_db.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(ParseSensorJson, ReadsTheDesignFields) {
  const auto r = ParseSensorJson(
      R"({"compass_yaw_deg": -10.5, "inclinometer_pitch_deg": 1.0, "inclinometer_roll_deg": null, "lat": 46.2})", "x");
  ASSERT_TRUE(r.compass_deg);
  EXPECT_NEAR(*r.compass_deg, 349.5, 1e-12);
  EXPECT_NEAR(*r.pitch_deg, 1.0, 1e-12);
  EXPECT_FALSE(r.roll_deg);
  EXPECT_FALSE(r.lon_deg);
}

TEST(ParseSensorJson, BadValuesNameTheFileAndField) {
  try {
    ParseSensorJson(R"({"inclinometer_pitch_deg": 120})", "s.json");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("s.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("inclinometer_pitch_deg"), std::string::npos);
  }
  EXPECT_THROW(ParseSensorJson(R"({"compass_yaw_deg": "north"})", "s"), InvalidArgument);
  EXPECT_THROW(ParseSensorJson("[1,2", "s"), InvalidArgument);
  EXPECT_THROW(ReadSensorJson("/nonexistent/sensors.json"), IoError);
}

TEST(ReadExif, GpsDirectionAndFocalRoundTrip) {
  const auto path = std::filesystem::temp_directory_path() / "horizonreg_exif_test.jpg";
  cv::imwrite(path.string(), cv::Mat(32, 48, CV_8UC3, cv::Scalar(200, 150, 100)));
  {
    auto image = Exiv2::ImageFactory::open(path.string());
    image->readMetadata();
    Exiv2::ExifData& exif = image->exifData();
    exif["Exif.GPSInfo.GPSLatitudeRef"] = "N";
    exif["Exif.GPSInfo.GPSLatitude"] = "46/1 14/1 2364/100";
    exif["Exif.GPSInfo.GPSLongitudeRef"] = "W";
    exif["Exif.GPSInfo.GPSLongitude"] = "121/1 31/1 2304/100";
    exif["Exif.GPSInfo.GPSAltitudeRef"] = Exiv2::byte(0);
    exif["Exif.GPSInfo.GPSAltitude"] = Exiv2::Rational(21059, 10);
    exif["Exif.GPSInfo.GPSImgDirectionRef"] = "T";
    exif["Exif.GPSInfo.GPSImgDirection"] = Exiv2::Rational(3465, 20);
    exif["Exif.Photo.FocalLengthIn35mmFilm"] = uint16_t(50);
    exif["Exif.Photo.PixelXDimension"] = uint32_t(6000);
    exif["Exif.Photo.PixelYDimension"] = uint32_t(4000);
    exif["Exif.Image.Orientation"] = uint16_t(6);
    image->writeMetadata();
  }
  const SensorReading r = ReadExif(path.string());
  std::filesystem::remove(path);
  ASSERT_TRUE(r.lat_deg && r.lon_deg && r.alt_m && r.compass_deg && r.focal_35mm);
  ASSERT_TRUE(r.recorded_width_px && r.recorded_height_px);
  EXPECT_EQ(*r.recorded_width_px, 6000);
  EXPECT_EQ(*r.recorded_height_px, 4000);
  EXPECT_TRUE(r.turned);
  EXPECT_NEAR(*r.lat_deg, 46 + 14 / 60.0 + 23.64 / 3600, 1e-9);
  EXPECT_NEAR(*r.lon_deg, -(121 + 31 / 60.0 + 23.04 / 3600), 1e-9);
  EXPECT_NEAR(*r.alt_m, 2105.9, 1e-9);
  EXPECT_NEAR(*r.compass_deg, 173.25, 1e-9);
  EXPECT_NEAR(*r.focal_35mm, 50.0, 1e-12);
}

// A photo with Make, Model and FocalLength (and optionally a 35 mm value).
SensorReading ExifOfBody(const std::string& tag, const std::string& make, const std::string& model,
                         Exiv2::Rational focal, int focal_35mm) {
  const auto path = std::filesystem::temp_directory_path() / ("horizonreg_exif_body_" + tag + ".jpg");
  cv::imwrite(path.string(), cv::Mat(32, 48, CV_8UC3, cv::Scalar(200, 150, 100)));
  {
    auto image = Exiv2::ImageFactory::open(path.string());
    image->readMetadata();
    Exiv2::ExifData& exif = image->exifData();
    exif["Exif.Image.Make"] = make;
    exif["Exif.Image.Model"] = model;
    exif["Exif.Photo.FocalLength"] = focal;
    if (focal_35mm > 0) exif["Exif.Photo.FocalLengthIn35mmFilm"] = uint16_t(focal_35mm);
    image->writeMetadata();
  }
  const SensorReading r = ReadExif(path.string());
  std::filesystem::remove(path);
  return r;
}

TEST(CameraCropFactor, KnownBodiesFromLensfun) {
  // APS-C Canon (22.2 x 14.8 mm), DX Nikon, full frame.
  const auto canon = CameraCropFactor("Canon", "Canon EOS 40D");
  ASSERT_TRUE(canon.has_value());
  EXPECT_NEAR(*canon, 1.62, 0.01);
  const auto nikon = CameraCropFactor("NIKON CORPORATION", "NIKON D200");
  ASSERT_TRUE(nikon.has_value());
  EXPECT_NEAR(*nikon, 1.52, 0.02);
  const auto ff = CameraCropFactor("Canon", "Canon EOS 5D Mark II");
  ASSERT_TRUE(ff.has_value());
  EXPECT_NEAR(*ff, 1.0, 0.01);
  EXPECT_FALSE(CameraCropFactor("Nobody", "No Such Camera 9000").has_value());
  EXPECT_FALSE(CameraCropFactor("", "Canon EOS 40D").has_value());
  EXPECT_FALSE(CameraCropFactor("Canon", "").has_value());
}

TEST(CameraCropFactor, ConcurrentLookupsAgree) {
  std::vector<std::thread> threads;
  std::vector<double> got(8, 0.0);
  for (int i = 0; i < 8; ++i)
    threads.emplace_back([&, i] { got[i] = CameraCropFactor("Canon", i % 2 ? "Canon EOS 40D" : "Canon EOS 7D").value_or(0.0); });
  for (auto& t : threads) t.join();
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(got[i], 1.6, 0.03) << i;
}

TEST(ReadExif, FocalLengthTimesTheBodysCropFactorWhenNo35mmValue) {
  const SensorReading canon = ExifOfBody("canon", "Canon", "Canon EOS 40D", Exiv2::Rational(24, 1), 0);
  ASSERT_TRUE(canon.focal_35mm.has_value());
  EXPECT_TRUE(canon.focal_35mm_from_crop_factor);
  EXPECT_NEAR(*canon.focal_35mm, 24.0 * 1.62, 0.3);
  // The photo's own 35 mm value wins.
  const SensorReading nikon = ExifOfBody("nikon", "NIKON CORPORATION", "NIKON D200", Exiv2::Rational(18, 1), 27);
  ASSERT_TRUE(nikon.focal_35mm.has_value());
  EXPECT_FALSE(nikon.focal_35mm_from_crop_factor);
  EXPECT_DOUBLE_EQ(*nikon.focal_35mm, 27.0);
  // A body nobody knows: no opening angle rather than a guess.
  const SensorReading unknown = ExifOfBody("unknown", "Nobody", "No Such Camera 9000", Exiv2::Rational(24, 1), 0);
  EXPECT_FALSE(unknown.focal_35mm.has_value());
  EXPECT_FALSE(unknown.focal_35mm_from_crop_factor);
}

TEST(ReadExif, NoMetadataOrNotAnImageGivesAnEmptyReading) {
  const auto path = std::filesystem::temp_directory_path() / "horizonreg_noexif_test.png";
  cv::imwrite(path.string(), cv::Mat(8, 8, CV_8UC1, cv::Scalar(0)));
  const SensorReading r = ReadExif(path.string());
  EXPECT_FALSE(r.lat_deg || r.compass_deg || r.focal_35mm);
  std::filesystem::remove(path);
  EXPECT_FALSE(ReadExif("/nonexistent.jpg").lat_deg);
}

TEST(HfovFromFocal35mm, FullFrameFiftyMillimetres) {
  // 36 x 24 mm frame at 50 mm: horizontal 39.6 deg.
  EXPECT_NEAR(HfovFromFocal35mm(50.0, 3000, 2000), 39.598, 0.01);
}

TEST(FrameOf, ACropOfOneSideKeepsTheCamerasFrame) {
  // Resized only (or no recorded size, or a recorded size of the same
  // shape): the image is the frame, as before.
  for (const auto& [rw, rh] : {std::pair{6000, 4000}, std::pair{6001, 4000}, std::pair{0, 0}}) {
    const Frame35mm f = FrameOf(1500, 1000, rw > 0 ? std::optional<int>(rw) : std::nullopt,
                                rh > 0 ? std::optional<int>(rh) : std::nullopt);
    EXPECT_FALSE(f.cropped);
    EXPECT_DOUBLE_EQ(f.width, 1500.0);
    EXPECT_DOUBLE_EQ(f.height, 1000.0);
  }
  // 3/4 of the width of a 6000 x 4000 photo resized to 1125 x 1000: the
  // frame is 1500 x 1000 and the opening angle 3/4 of the frame's in tan.
  const Frame35mm f = FrameOf(1125, 1000, 6000, 4000);
  EXPECT_TRUE(f.cropped);
  EXPECT_NEAR(f.width, 1500.0, 1e-9);
  EXPECT_NEAR(f.height, 1000.0, 1e-9);
  const double full = HfovFromFocal35mm(50.0, 1500, 1000);
  EXPECT_NEAR(std::tan(HfovFromFocal35mm(50.0, 1125, f) * kPi / 360.0), 0.75 * std::tan(full * kPi / 360.0), 1e-12);
  // The same crop of a portrait photo (the recorded size is the stored
  // pixels', landscape; the decoded image is turned upright): the frame is
  // portrait too.
  const Frame35mm p = FrameOf(1000, 1125, 6000, 4000, /*turned=*/true);
  EXPECT_TRUE(p.cropped);
  EXPECT_NEAR(p.width, 1000.0, 1e-9);
  EXPECT_NEAR(p.height, 1500.0, 1e-9);
  // A turned photo resized only: no crop.
  EXPECT_FALSE(FrameOf(1000, 1500, 6000, 4000, true).cropped);
  // A portrait crop of a landscape photo (not turned: half its width): the
  // height is whole.
  const Frame35mm q = FrameOf(750, 1000, 6000, 4000);
  EXPECT_TRUE(q.cropped);
  EXPECT_NEAR(q.width, 1500.0, 1e-9);
  EXPECT_NEAR(q.height, 1000.0, 1e-9);
  // A letterbox (16:9 from 3:2): the width is whole.
  const Frame35mm l = FrameOf(1920, 1080, 6000, 4000);
  EXPECT_TRUE(l.cropped);
  EXPECT_NEAR(l.width, 1920.0, 1e-9);
  EXPECT_NEAR(l.height, 1280.0, 1e-9);
}

}  // namespace
}  // namespace horizonreg

namespace horizonreg {
namespace {

TEST(ReadSensorLog, SkipsGarbageWithWarningsAndFindsFrames) {
  const auto path = std::filesystem::temp_directory_path() / "hr_sensor_log.csv";
  std::ofstream(path) << "frame,compass_yaw_deg,inclinometer_pitch_deg,inclinometer_roll_deg\n"
                         "0,36.8,-3.2,-1.1\n"
                         "1,garbage,-3.0,0.1\n"
                         "2,nan,-3.0,0.0\n"
                         "3,37.7,-2.6,-0.2\n"
                         "what is this line\n"
                         "5,38.0,,0.3\n";
  const SensorLog log = ReadSensorLog(path.string());
  std::filesystem::remove(path);
  EXPECT_EQ(log.entries.size(), 3u);
  EXPECT_EQ(log.warnings.size(), 3u);
  ASSERT_TRUE(log.ForFrame(3, 10.0));
  EXPECT_NEAR(*log.ForFrame(3, 10.0)->compass_deg, 37.7, 1e-12);
  EXPECT_FALSE(log.ForFrame(4, 10.0));  // missing frame
  EXPECT_FALSE(log.ForFrame(5, 10.0)->pitch_deg);
  EXPECT_NE(log.warnings[0].find("line 3"), std::string::npos) << log.warnings[0];
}

TEST(ReadSensorLog, TimeColumnsAndBadFiles) {
  const auto dir = std::filesystem::temp_directory_path();
  const auto timed = dir / "hr_sensor_time.json", headless = dir / "hr_sensor_bad.csv";
  std::ofstream(timed) << R"([{"time_s": 0.0, "compass_yaw_deg": 10}, {"time_s": 0.1, "compass_yaw_deg": 11}])";
  std::ofstream(headless) << "a,b,c\n1,2,3\n";
  const SensorLog log = ReadSensorLog(timed.string());
  ASSERT_TRUE(log.ForFrame(1, 10.0));
  EXPECT_NEAR(*log.ForFrame(1, 10.0)->compass_deg, 11.0, 1e-12);
  EXPECT_THROW(ReadSensorLog(headless.string()), InvalidArgument);
  EXPECT_THROW(ReadSensorLog((dir / "hr_nonexistent.csv").string()), IoError);
  std::filesystem::remove(timed), std::filesystem::remove(headless);
}

TEST(SensorCalibrator, RecoversOffsetAndDriftDespiteAnOutlier) {
  SensorCalibrator cal;
  for (int i = 0; i < 40; ++i) {
    const double t = i * 0.1, az = 358.0 + 0.5 * i;  // crosses north
    SensorReading raw;
    raw.compass_deg = WrapAzimuthDeg(az - (7.0 + 0.25 * t) + (i == 13 ? 20.0 : 0.0));
    raw.pitch_deg = -3.0 - 1.2;
    raw.roll_deg = 0.5 + 0.8;
    cal.Add(t, raw, WrapAzimuthDeg(az), -3.0, 0.5);
  }
  const auto c = cal.Estimate();
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->compass_offset_deg, 7.0, 1e-6);
  EXPECT_NEAR(c->compass_drift_deg_per_s, 0.25, 1e-6);
  EXPECT_NEAR(c->pitch_offset_deg, 1.2, 1e-9);
  EXPECT_NEAR(c->roll_offset_deg, -0.8, 1e-9);
  SensorReading raw;
  raw.compass_deg = 100.0;
  EXPECT_NEAR(*c->Apply(raw, 5.0).compass_deg, 100.0 + 7.0 + 0.25 * 5.0, 1e-6);
  const auto path = std::filesystem::temp_directory_path() / "hr_cal.json";
  c->Save(path.string());
  const SensorCalibration back = SensorCalibration::Load(path.string());
  std::filesystem::remove(path);
  EXPECT_NEAR(back.compass_drift_deg_per_s, 0.25, 1e-9);
  EXPECT_FALSE(SensorCalibrator{}.Estimate());
}

}  // namespace
}  // namespace horizonreg
