// SPDX-License-Identifier: MIT
#include "pipeline/camera_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <random>

#include "util/errors.h"

namespace horizonreg {
namespace {

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("horizonreg_camera_file_test_" + name)).string();
}

std::string Write(const std::string& name, const std::string& text) {
  const std::string p = TempPath(name);
  std::ofstream(p) << text;
  return p;
}

TEST(ReadCameraFile, PlainJsonInDesignConvention) {
  const std::string p = Write("plain.json",
                              R"({"camera": {"fx_px": 1000, "fy_px": 990, "cx_px": 470.5, "cy_px": 330.25,
                                  "k": [-0.1, 0.05], "p": [0.001, -0.002], "width": 968, "height": 648}})");
  const CameraIntrinsics k = ReadCameraFile(p, 968, 648);
  EXPECT_DOUBLE_EQ(k.focal_px, 1000.0);
  EXPECT_DOUBLE_EQ(k.FocalYPx(), 990.0);
  EXPECT_DOUBLE_EQ(k.cx_px, 470.5);
  EXPECT_DOUBLE_EQ(k.cy_px, 330.25);
  EXPECT_DOUBLE_EQ(k.distortion.k()[0], -0.1);
  EXPECT_DOUBLE_EQ(k.distortion.k()[1], 0.05);
  EXPECT_DOUBLE_EQ(k.distortion.p()[1], -0.002);
  // The same camera for a photo resized to half.
  const CameraIntrinsics h = ReadCameraFile(p, 484, 324);
  EXPECT_DOUBLE_EQ(h.focal_px, 500.0);
  EXPECT_DOUBLE_EQ(h.cx_px, 235.25);
  EXPECT_DOUBLE_EQ(h.distortion.k()[0], -0.1);  // on normalised coordinates: unchanged
  EXPECT_THROW(ReadCameraFile(p, 968, 500), InvalidArgument);  // a crop
}

TEST(ReadCameraFile, PlainJsonDefaultsToTheImageCentre) {
  const CameraIntrinsics k = ReadCameraFile(Write("min.json", R"({"focal_px": 800})"), 640, 480);
  EXPECT_DOUBLE_EQ(k.cx_px, 320.0);
  EXPECT_DOUBLE_EQ(k.cy_px, 240.0);
  EXPECT_TRUE(k.distortion.IsIdentity());
  EXPECT_TRUE(k.IsCentredPinhole());
}

TEST(ReadCameraFile, OpenCvYamlShiftsThePrincipalPointByHalfAPixel) {
  const std::string p = TempPath("opencv.yaml");
  {
    cv::FileStorage fs(p, cv::FileStorage::WRITE);
    fs << "image_width" << 1000 << "image_height" << 800;
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << 900, 0, 499.5, 0, 905, 399.5, 0, 0, 1);
    fs << "distortion_coefficients" << (cv::Mat_<double>(1, 5) << -0.2, 0.1, 0.001, 0.002, -0.01);
  }
  const CameraIntrinsics k = ReadCameraFile(p, 1000, 800);
  EXPECT_DOUBLE_EQ(k.cx_px, 500.0);
  EXPECT_DOUBLE_EQ(k.cy_px, 400.0);
  EXPECT_DOUBLE_EQ(k.FocalYPx(), 905.0);
  EXPECT_DOUBLE_EQ(k.distortion.k()[2], -0.01);  // k3 is the fifth coefficient
  EXPECT_DOUBLE_EQ(k.distortion.p()[0], 0.001);
  // Also as OpenCV's JSON.
  const std::string pj = TempPath("opencv.json");
  {
    cv::FileStorage fs(pj, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_JSON);
    fs << "cameraMatrix" << (cv::Mat_<double>(3, 3) << 900, 0, 499.5, 0, 905, 399.5, 0, 0, 1);
    fs << "distCoeffs" << (cv::Mat_<double>(1, 4) << -0.2, 0.1, 0.0, 0.0);
  }
  EXPECT_DOUBLE_EQ(ReadCameraFile(pj, 1000, 800).cx_px, 500.0);
}

// Our projection through the lens equals OpenCV's projectPoints (shifted by
// the half pixel of the conventions), an independent implementation of the
// same model.
TEST(ReadCameraFile, ProjectionAgreesWithOpenCvProjectPoints) {
  const std::string p = TempPath("rational.yaml");
  const cv::Mat km = (cv::Mat_<double>(3, 3) << 1005, 0, 482.6, 0, 1010, 326.9, 0, 0, 1);
  const cv::Mat dm = (cv::Mat_<double>(1, 8) << -0.12, 0.11, -0.003, 0.001, 0.02, 0.01, -0.02, 0.03);
  {
    cv::FileStorage fs(p, cv::FileStorage::WRITE);
    fs << "camera_matrix" << km << "distortion_coefficients" << dm;
  }
  const CameraIntrinsics k = ReadCameraFile(p, 968, 648);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.6, 0.6), v(-0.4, 0.4);
  std::vector<cv::Point3d> pts;
  for (int i = 0; i < 200; ++i) pts.emplace_back(u(rng), v(rng), 1.0);
  std::vector<cv::Point2d> ref;
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), km, dm, ref);
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto px = k.PixelFromNormalized({pts[i].x, pts[i].y});
    ASSERT_TRUE(px);
    EXPECT_NEAR(px->x(), PixelFromOpenCv(ref[i].x), 1e-9);
    EXPECT_NEAR(px->y(), PixelFromOpenCv(ref[i].y), 1e-9);
    const auto back = k.NormalizedFromPixel(*px);
    ASSERT_TRUE(back);
    EXPECT_NEAR(back->x(), pts[i].x, 1e-9);
    EXPECT_NEAR(back->y(), pts[i].y, 1e-9);
  }
}

TEST(ReadCameraFile, BadFilesGiveOneClearError) {
  EXPECT_THROW(ReadCameraFile(TempPath("missing.json"), 640, 480), IoError);
  EXPECT_THROW(ReadCameraFile(Write("garbage.txt", "\x01\x02 not a camera"), 640, 480), InvalidArgument);
  EXPECT_THROW(ReadCameraFile(Write("nofocal.json", R"({"cx_px": 3})"), 640, 480), InvalidArgument);
  EXPECT_THROW(ReadCameraFile(Write("negfocal.json", R"({"focal_px": -3})"), 640, 480), InvalidArgument);
  EXPECT_THROW(ReadCameraFile(Write("badk.json", R"({"focal_px": 500, "k": ["a"]})"), 640, 480), InvalidArgument);
  EXPECT_THROW(ReadCameraFile(Write("nank.json", R"({"focal_px": 500, "k": [1e300]})"), 640, 480), InvalidArgument);
  try {
    ReadCameraFile(Write("nofocal2.json", R"({"cx_px": 3})"), 640, 480);
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("nofocal2.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace horizonreg
