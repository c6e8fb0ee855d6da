// SPDX-License-Identifier: MIT
// Known camera intrinsics from a file (`--camera`, DESIGN.md): focal length,
// principal point and lens distortion, used exactly by registration, the
// overlay, rendering and tracking.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

#include "camera/camera.h"

namespace horizonreg {

// Reads a camera file and returns its intrinsics for an image of
// image_width x image_height pixels. Formats:
//  - OpenCV calibration output written by cv::FileStorage, YAML or JSON (not
//    XML nor .gz: OpenCV 4.6's XML reader crashes on malformed files):
//    `camera_matrix` (3 x 3; also `cameraMatrix`, `K`),
//    `distortion_coefficients` (k1, k2, p1, p2[, k3[, k4, k5, k6]]; also
//    `distCoeffs`, `D`), optional `image_width`, `image_height`. OpenCV puts
//    pixel centres on whole numbers: its principal point is moved by +0.5 px
//    into DESIGN.md's convention (PixelFromOpenCv).
//  - A plain JSON object in DESIGN.md's pixel convention (origin at the
//    top-left corner of the top-left pixel), at the top level or under
//    "camera": "focal_px" (or "fx_px"), optional "fy_px", "cx_px", "cy_px"
//    (default: the image centre), "k": [k1, ...], "p": [p1, p2], optional
//    "width", "height".
// A file for another image size (a full-resolution calibration, a resized
// photo) is scaled to this one; a different aspect ratio (a crop) is an
// error. Throws IoError when the file cannot be read, InvalidArgument naming
// the file and the field when its content is wrong. Thread-safe.
CameraIntrinsics ReadCameraFile(const std::string& path, int image_width, int image_height);

// The plain JSON layout above, already parsed (e.g. the "camera" block of a
// register JSON); `source` names it in errors.
CameraIntrinsics CameraFromJson(const nlohmann::json& camera, int image_width, int image_height,
                                const std::string& source);

// DESIGN.md pixel coordinate of an OpenCV pixel coordinate (OpenCV: the
// centre of the top-left pixel is (0, 0); here it is (0.5, 0.5)), and back.
// The one place the two conventions meet.
inline double PixelFromOpenCv(double opencv_px) { return opencv_px + 0.5; }
inline double OpenCvFromPixel(double px) { return px - 0.5; }

}  // namespace horizonreg
