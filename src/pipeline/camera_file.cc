// SPDX-License-Identifier: MIT
#include "pipeline/camera_file.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <sstream>

#include "util/errors.h"
#include "util/text.h"

namespace horizonreg {
namespace {

[[noreturn]] void Bad(const std::string& path, const std::string& what) {
  throw InvalidArgument("camera: '" + path + "': " + what);
}

double Positive(const std::string& path, const char* field, double v) {
  if (!(v > 0.0) || !std::isfinite(v)) Bad(path, std::string(field) + " must be a positive number");
  return v;
}

// Scales intrinsics given for file_w x file_h to the image size.
CameraIntrinsics Scaled(const std::string& path, CameraIntrinsics k, int image_width, int image_height) {
  if (k.width == image_width && k.height == image_height) return k;
  const double sx = static_cast<double>(image_width) / k.width, sy = static_cast<double>(image_height) / k.height;
  if (std::abs(sx / sy - 1.0) > 0.01) {
    std::ostringstream m;
    m << "calibrated for " << k.width << " x " << k.height << ", the photo is " << image_width << " x "
      << image_height << " (another aspect ratio: a cropped photo cannot use it)";
    Bad(path, m.str());
  }
  return k.Resized(image_width, image_height);
}

std::vector<double> NumberArray(const std::string& path, const nlohmann::json& j, const char* field) {
  std::vector<double> v;
  if (!j.contains(field)) return v;
  if (!j[field].is_array()) Bad(path, std::string("\"") + field + "\" must be an array of numbers");
  for (const auto& x : j[field]) {
    if (!x.is_number()) Bad(path, std::string("\"") + field + "\" must be an array of numbers");
    v.push_back(x.get<double>());
  }
  return v;
}

// The intrinsics read from `path`, checked (errors name the file) and scaled
// to the image.
CameraIntrinsics Checked(const std::string& path, CameraIntrinsics k, int image_width, int image_height) {
  try {
    k.Check();
  } catch (const InvalidArgument& e) {
    Bad(path, e.what());
  }
  return Scaled(path, k, image_width, image_height);
}

CameraIntrinsics FromPlainJson(const std::string& path, const nlohmann::json& root, int image_width, int image_height) {
  const nlohmann::json& j = root.contains("camera") && root["camera"].is_object() ? root["camera"] : root;
  auto number = [&](const char* field) -> std::optional<double> {
    if (!j.contains(field) || j[field].is_null()) return std::nullopt;
    if (!j[field].is_number()) Bad(path, std::string("\"") + field + "\" must be a number");
    return j[field].get<double>();
  };
  CameraIntrinsics k;
  const auto w = number("width"), h = number("height");
  if (w.has_value() != h.has_value()) Bad(path, "give both \"width\" and \"height\" or neither");
  k.width = w ? static_cast<int>(std::lround(Positive(path, "width", *w))) : image_width;
  k.height = h ? static_cast<int>(std::lround(Positive(path, "height", *h))) : image_height;
  const auto fx = number("focal_px") ? number("focal_px") : number("fx_px");
  if (!fx) Bad(path, "no \"focal_px\" (or \"fx_px\")");
  k.focal_px = Positive(path, "focal_px", *fx);
  if (const auto fy = number("fy_px")) k.aspect = Positive(path, "fy_px", *fy) / k.focal_px;
  k.cx_px = number("cx_px").value_or(k.width / 2.0);
  k.cy_px = number("cy_px").value_or(k.height / 2.0);
  try {
    k.distortion = LensDistortion(NumberArray(path, j, "k"), NumberArray(path, j, "p"));
  } catch (const InvalidArgument& e) {
    Bad(path, e.what());
  }
  return Checked(path, k, image_width, image_height);
}

CameraIntrinsics FromOpenCv(const std::string& path, int image_width, int image_height) {
  cv::FileStorage fs;
  try {
    if (!fs.open(path, cv::FileStorage::READ)) Bad(path, "not an OpenCV calibration file (YAML/JSON) nor a camera JSON");
  } catch (const std::exception&) {  // cv::Exception, and std::length_error from OpenCV 4.6's YAML parser (fuzz_camera_file)
    Bad(path, "not an OpenCV calibration file (YAML/JSON) nor a camera JSON");
  }
  // fs[name] asserts (cv::Exception) when a top-level node is not a map,
  // e.g. "%YAML:1.0\n- 1" (found by fuzz/fuzz_camera_file.cc).
  const auto top = [&](const char* name) {
    try {
      return fs[name];
    } catch (const cv::Exception&) {
      Bad(path, "not an OpenCV calibration file (YAML/JSON) nor a camera JSON");
    }
  };
  auto matrix = [&](std::initializer_list<const char*> names) {
    cv::Mat m;
    for (const char* n : names) {
      const cv::FileNode node = top(n);
      if (node.empty()) continue;
      try {
        // OpenCV allocates rows x cols before reading the data: a garbled
        // size (a non-number reads as INT_MAX) would ask for gigabytes
        // (found by fuzz/fuzz_camera_file.cc). The matrices here are at
        // most 3 x 3 and 1 x 14.
        const auto small = [](const cv::FileNode& d) { return d.isInt() && int(d) >= 1 && int(d) <= 16; };
        if (!node.isMap() || !small(node["rows"]) || !small(node["cols"]))
          Bad(path, std::string("\"") + n + "\" is not a matrix of at most 16 x 16");
        node >> m;
      } catch (const cv::Exception&) {
        Bad(path, std::string("\"") + n + "\" is not a matrix");
      }
      if (!m.empty()) break;
    }
    cv::Mat d;
    if (!m.empty()) m.convertTo(d, CV_64F);
    return d;
  };
  const cv::Mat km = matrix({"camera_matrix", "cameraMatrix", "K"});
  if (km.rows != 3 || km.cols != 3) Bad(path, "no 3 x 3 camera_matrix");
  const cv::Mat dm = matrix({"distortion_coefficients", "distCoeffs", "D"});
  const int n = static_cast<int>(dm.total());
  if (!dm.empty() && n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
    Bad(path, "distortion_coefficients must hold 4, 5, 8, 12 or 14 values (k1, k2, p1, p2[, k3[, k4, k5, k6 ...]])");
  if (n > 8) {
    const double* d = dm.ptr<double>();
    for (int i = 8; i < n; ++i)
      if (d[i] != 0.0) Bad(path, "thin-prism and tilted-sensor coefficients (s1..s4, tx, ty) are not supported");
  }
  CameraIntrinsics k;
  int w = 0, h = 0;
  if (!top("image_width").empty()) top("image_width") >> w;
  if (!top("image_height").empty()) top("image_height") >> h;
  if ((w > 0) != (h > 0)) Bad(path, "give both image_width and image_height or neither");
  k.width = w > 0 ? w : image_width;
  k.height = h > 0 ? h : image_height;
  k.focal_px = Positive(path, "camera_matrix fx", km.at<double>(0, 0));
  k.aspect = Positive(path, "camera_matrix fy", km.at<double>(1, 1)) / k.focal_px;
  if (std::abs(km.at<double>(0, 1)) > 1e-9 * k.focal_px) Bad(path, "camera_matrix has a skew term; not supported");
  k.cx_px = PixelFromOpenCv(km.at<double>(0, 2));
  k.cy_px = PixelFromOpenCv(km.at<double>(1, 2));
  if (n > 0) {
    const double* d = dm.ptr<double>();
    std::vector<double> kk = {d[0], d[1]};
    if (n >= 5) kk.push_back(d[4]);
    if (n >= 8) kk.insert(kk.end(), {d[5], d[6], d[7]});
    try {
      k.distortion = LensDistortion(kk, {d[2], d[3]});
    } catch (const InvalidArgument& e) {
      Bad(path, e.what());
    }
  }
  return Checked(path, k, image_width, image_height);
}

}  // namespace

CameraIntrinsics CameraFromJson(const nlohmann::json& camera, int image_width, int image_height,
                                const std::string& source) {
  return FromPlainJson(source, camera, image_width, image_height);
}

CameraIntrinsics ReadCameraFile(const std::string& path, int image_width, int image_height) {
  // Bounded before it is read (a camera file is a few KB).
  const std::string s = ReadTextFile(path, "camera", size_t{16} << 20);
  const nlohmann::json j = nlohmann::json::parse(s, nullptr, /*allow_exceptions=*/false);
  if (j.is_object()) {
    const nlohmann::json& c = j.contains("camera") && j["camera"].is_object() ? j["camera"] : j;
    if (c.contains("focal_px") || c.contains("fx_px")) return FromPlainJson(path, j, image_width, image_height);
  }
  // OpenCV 4.6's XML reader dereferences a null pointer on malformed input
  // ("<?xml vsion=", found by fuzz/fuzz_camera_file.cc), and FileStorage
  // picks it by the content or the .xml extension (and reads .gz files
  // through zlib, content unseen here): camera files are YAML or JSON.
  const std::string ext = std::filesystem::path(path).extension().string();
  const size_t first = s.find_first_not_of(" \t\r\n");
  if ((first != std::string::npos && s[first] == '<') || ext == ".xml" || ext == ".XML" || ext == ".gz" || ext == ".GZ")
    Bad(path, "XML and compressed calibration files are not read; save it as YAML or JSON");
  return FromOpenCv(path, image_width, image_height);
}

}  // namespace horizonreg
