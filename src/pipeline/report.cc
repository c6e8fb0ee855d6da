// SPDX-License-Identifier: MIT
#include "pipeline/report.h"

#include <algorithm>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "overlay/overlay.h"
#include "util/angles.h"
#include "util/json.h"

namespace horizonreg {

nlohmann::json SkylineJson(const Skyline& s) {
  nlohmann::json j;
  j["width"] = s.width;
  j["height"] = s.height;
  nlohmann::json ys = nlohmann::json::array(), cs = nlohmann::json::array();
  for (int x = 0; x < s.width; ++x) {
    ys.push_back(Rounded(s.y[x], 2));
    cs.push_back(Rounded(s.confidence[x], 3));
  }
  j["y"] = std::move(ys);
  j["confidence"] = std::move(cs);
  // The clearer edge below a raised boundary, which the matching reads
  // (Skyline::y_alt): written where any is set, so that `register
  // --skyline` given this file matches what it would have extracted.
  if (std::any_of(s.y_alt.begin(), s.y_alt.end(), [](double v) { return std::isfinite(v); })) {
    nlohmann::json alt = nlohmann::json::array();
    for (int x = 0; x < s.width; ++x) alt.push_back(Rounded(s.Alt(x), 2));
    j["y_alt"] = std::move(alt);
  }
  j["visible_columns"] = s.VisibleCount();
  return j;
}

nlohmann::json RegistrationReport(const Site& site, const PhotoRegistration& photo, const std::string& position_source,
                                  double total_ms) {
  const Registration& r = photo.registration;
  const RegistrationOptions& ro = photo.options;
  const HorizonProfile& profile = site.horizon();
  nlohmann::json j;
  j["status"] = r.registered ? "registered" : "no_match";
  j["message"] = r.message;
  j["observer"] = {{"lat", Rounded(profile.observer.lat_deg, 7)},
                   {"lon", Rounded(profile.observer.lon_deg, 7)},
                   {"eye_height_m", Rounded(profile.observer.height_m, 2)},
                   {"source", position_source}};
  j["width"] = photo.width;
  j["height"] = photo.height;
  const auto pose_field = [&](double v, int decimals) { return r.registered ? Rounded(v, decimals) : nullptr; };
  j["azimuth_deg"] = pose_field(r.pose.azimuth_deg, 4);
  j["pitch_deg"] = pose_field(r.pose.pitch_deg, 4);
  j["roll_deg"] = pose_field(r.pose.roll_deg, 4);
  j["hfov_deg"] = pose_field(r.hfov_deg, 4);
  j["center_ray"] = {{"azimuth_deg", pose_field(r.center_ray.azimuth_deg, 4)},
                     {"elevation_deg", pose_field(r.center_ray.pitch_deg, 4)}};
  j["focal_px"] = pose_field(r.focal_px, 2);
  j["cx_px_per_deg"] = pose_field(DegToRad(r.focal_px), 3);
  j["cy_px_per_deg"] = pose_field(DegToRad(r.focal_px), 3);
  j["azimuth_sigma_deg"] = pose_field(r.azimuth_sigma_deg, 4);
  j["pitch_sigma_deg"] = pose_field(r.pitch_sigma_deg, 4);
  j["roll_sigma_deg"] = pose_field(r.roll_sigma_deg, 4);
  {
    const CameraIntrinsics& k = r.intrinsics;
    nlohmann::json cam = {{"source", ro.known_intrinsics ? "file" : "fitted"}};
    if (k.width > 0) {
      cam["focal_px"] = Rounded(k.focal_px, 2);
      cam["fy_px"] = Rounded(k.FocalYPx(), 2);
      cam["cx_px"] = Rounded(k.cx_px, 2);
      cam["cy_px"] = Rounded(k.cy_px, 2);
      nlohmann::json kk = nlohmann::json::array(), pp = nlohmann::json::array();
      for (double v : k.distortion.k()) kk.push_back(Rounded(v, 5));
      for (double v : k.distortion.p()) pp.push_back(Rounded(v, 5));
      cam["k"] = kk;
      cam["p"] = pp;
    }
    cam["k1_estimated"] = r.distortion_estimated;
    cam["k1_sigma"] = Rounded(r.k1_sigma, 4);
    j["camera"] = cam;
    j["dem"] = {{"post_spacing_m", Rounded(r.dem.post_spacing_m, 1)},
                {"horizon_distance_m", Rounded(r.dem.horizon_distance_m, 0)},
                {"expected_flattening_px", Rounded(r.dem.expected_flattening_px, 2)},
                {"skyline_above_dem_px", Rounded(r.dem.skyline_above_dem_px, 2)},
                {"dem_explained_fraction", Rounded(r.dem.dem_explained_fraction, 3)},
                {"flattening_scale", Rounded(r.dem.flattening_scale, 2)}};
  }
  j["rms_px"] = Rounded(r.rms_px, 3);
  j["model_rms_px"] = Rounded(r.model_rms_px, 3);
  j["ex_px"] = Rounded(r.ex_px, 3);
  j["ey_px"] = Rounded(r.ey_px, 3);
  j["inlier_fraction"] = Rounded(r.inlier_fraction, 3);
  j["ambiguity_ratio"] = Rounded(std::min(r.ambiguity_ratio, 1e6), 2);
  j["second_inlier_fraction"] = Rounded(r.second_inlier_fraction, 3);
  j["evidence"] = {{"misfit", Rounded(r.misfit, 3)},
                   {"second_misfit", Rounded(r.second_misfit, 3)},
                   {"informative_columns", Rounded(r.informative_columns, 1)},
                   {"independent_inliers", Rounded(r.independent_inliers, 1)},
                   {"outliers_below", r.outliers_below},
                   {"outliers_above", r.outliers_above},
                   {"outliers_hidden", r.hidden_columns},
                   {"unhidden_inlier_fraction", Rounded(r.unhidden_inlier_fraction, 3)},
                   {"nats", Rounded(r.evidence_nats, 1)}};
  j["hypotheses"] = r.hypotheses;
  if (r.scanned_hypotheses > 0) j["scanned_hypotheses"] = r.scanned_hypotheses;
  auto candidate = [&](const PoseCandidate& c) {
    return nlohmann::json{{"azimuth_deg", Rounded(c.pose.azimuth_deg, 3)},
                          {"pitch_deg", Rounded(c.pose.pitch_deg, 3)},
                          {"roll_deg", Rounded(c.pose.roll_deg, 3)},
                          {"hfov_deg", Rounded(HfovFromFocalDeg(c.focal_px, photo.width), 3)},
                          {"cost", Rounded(c.cost, 4)},
                          {"inlier_fraction", Rounded(c.inlier_fraction, 3)}};
  };
  nlohmann::json alternatives = nlohmann::json::array();
  for (const PoseCandidate& c : r.candidates) alternatives.push_back(candidate(c));
  j["candidates"] = alternatives;
  // The distinct alternative the ambiguity ratio is taken against (null when
  // none was found or the pose was refined from a given start).
  j["rival"] = r.rival ? candidate(*r.rival) : nlohmann::json(nullptr);
  j["extrema"] = {{"image", r.image_extrema}, {"horizon", r.horizon_extrema}};
  const Skyline& skyline = photo.skyline;
  j["skyline_visible_fraction"] =
      skyline.width > 0 ? Rounded(static_cast<double>(skyline.VisibleCount()) / skyline.width, 3) : nullptr;
  j["hfov_search_deg"] = {Rounded(ro.min_hfov_deg, 2), Rounded(ro.max_hfov_deg, 2), photo.fov_source};
  nlohmann::json prior = nlohmann::json::object();
  if (ro.prior.compass_deg) prior["compass_deg"] = Rounded(*ro.prior.compass_deg, 3);
  if (ro.prior.pitch_deg) prior["pitch_deg"] = Rounded(*ro.prior.pitch_deg, 3);
  if (ro.prior.roll_deg) prior["roll_deg"] = Rounded(*ro.prior.roll_deg, 3);
  j["priors"] = prior;
  // "horizon" keeps its meaning (the DEM read and the horizon); "dem_load"
  // says how much of it was reading the DEM window.
  j["timing_ms"] = {{"horizon", Rounded(site.load_ms() + site.horizon_ms(), 1)},
                    {"dem_load", Rounded(site.load_ms(), 1)},
                    {"skyline", Rounded(photo.skyline_ms, 1)},
                    {"match", Rounded(photo.match_ms, 1)},
                    {"total", Rounded(total_ms, 1)}};
  if (photo.position) {
    const PositionEstimate& e = *photo.position;
    const char* axes[3] = {"east", "north", "up"};
    const char* angles[4] = {"azimuth", "pitch", "roll", "focal"};
    nlohmann::json corr = nlohmann::json::object(), observable = nlohmann::json::object();
    for (int k = 0; k < 3; ++k) {
      observable[axes[k]] = e.observable_axis[k];
      nlohmann::json row = nlohmann::json::object();
      for (int a = 0; a < 4; ++a) row[angles[a]] = Rounded(e.correlation(k, a), 3);
      corr[axes[k]] = row;
    }
    j["position"] = {{"lat", Rounded(e.observer.lat_deg, 8)},
                     {"lon", Rounded(e.observer.lon_deg, 8)},
                     {"eye_height_m", Rounded(e.observer.height_m, 2)},
                     {"sigma_east_m", Rounded(e.sigma_enu_m(0), 2)},
                     {"sigma_north_m", Rounded(e.sigma_enu_m(1), 2)},
                     {"sigma_up_m", Rounded(e.sigma_enu_m(2), 2)},
                     {"observable", e.observable},
                     {"observable_axes", observable},
                     {"offset_east_m", Rounded(e.offset_enu_m(0), 2)},
                     {"offset_north_m", Rounded(e.offset_enu_m(1), 2)},
                     {"offset_up_m", Rounded(e.offset_enu_m(2), 2)},
                     {"prior_sigma_m", {Rounded(e.prior_sigma_enu_m(0), 2), Rounded(e.prior_sigma_enu_m(2), 2)}},
                     {"correlation", corr},
                     {"azimuth_sigma_deg", Rounded(e.azimuth_sigma_deg, 4)},
                     {"pitch_sigma_deg", Rounded(e.pitch_sigma_deg, 4)},
                     {"horizons", e.horizons},
                     {"message", e.message}};
    j["timing_ms"]["position"] = Rounded(photo.position_ms, 1);
  }
  if (photo.ridge_check) {
    // The inner ridges' check of a pose refused for a rival: the share of
    // the ridge points on photo edges at the best pose and at each rival
    // checked, and which the ridges ruled out.
    const RidgeCheck& rc = *photo.ridge_check;
    nlohmann::json rivals = nlohmann::json::array();
    for (const RidgeCheck::Rival& v : rc.rivals) {
      nlohmann::json c = candidate(v.candidate);
      c["ridge_share"] = Rounded(v.support.Share(), 3);
      c["ridge_points"] = v.support.points;
      c["ruled_out"] = v.ruled_out;
      rivals.push_back(c);
    }
    j["ridge_check"] = {
        {"best_share", Rounded(rc.best.Share(), 3)}, {"best_points", rc.best.points}, {"rivals", rivals}};
  }
  if (photo.position_check) {
    // Whether the skyline fits clearly better from elsewhere (a wrong
    // position): the best place the check found and its cost ratio.
    const PositionCheck& c = *photo.position_check;
    j["position_check"] = {{"consistent", c.consistent},
                           {"cost_ratio", Rounded(c.cost_ratio, 3)},
                           {"best_offset_m", Rounded(c.OffsetM(), 0)},
                           {"best_bearing_deg", c.OffsetM() > 0.0 ? Rounded(c.BearingDeg(), 1) : nullptr},
                           {"best_azimuth_shift_deg", Rounded(c.AzimuthShiftDeg(), 2)},
                           {"best_pitch_shift_deg", Rounded(c.PitchShiftDeg(), 2)},
                           {"horizons", c.horizons},
                           {"wide_places", c.wide_places},
                           {"ridges_limit", c.only_ridges_limit},
                           {"lens_limit", c.only_lens_limit}};
    j["timing_ms"]["position_check"] = Rounded(c.ms, 1);
  }
  return j;
}

cv::Mat DrawRegistration(const Site& site, const cv::Mat& image, const PhotoRegistration& photo,
                         const std::string& landmarks_path) {
  const Registration& r = photo.registration;
  std::ostringstream caption;
  caption.precision(3);
  caption << std::fixed;
  if (r.registered) {
    caption << "registered: rms " << r.rms_px << " px, sigma az " << r.azimuth_sigma_deg << " pitch "
            << r.pitch_sigma_deg << " deg";
    OverlayOptions oo;
    oo.caption = caption.str();
    oo.eye_height_m = site.EyeAboveGroundM();
    return DrawOverlay(image, r.pose, r.Intrinsics(image.cols, image.rows),
                       {&photo.Horizon(site), &site.ridges(), OverlayLandmarks(site, landmarks_path)}, oo)
        .image;
  }
  caption << "no match: " << r.message;
  cv::Mat drawn = DrawSkylineDebug(image, photo.skyline);
  const double s = std::max(0.6, image.cols / 1000.0);
  const int halo = static_cast<int>(4 * s), margin = static_cast<int>(10 * s);
  // The reason in full, over as many lines as it takes (a no_match's
  // message, the second look's included, often runs past the width).
  int y = static_cast<int>(30 * s);
  for (const std::string& line : WrapText(caption.str(), 0.6 * s, halo, image.cols - 2 * margin, 8)) {
    const cv::Point at{margin, y};
    cv::putText(drawn, line, at, cv::FONT_HERSHEY_SIMPLEX, 0.6 * s, cv::Scalar(0, 0, 0), halo, cv::LINE_AA);
    cv::putText(drawn, line, at, cv::FONT_HERSHEY_SIMPLEX, 0.6 * s, cv::Scalar(255, 255, 255),
                std::max(1, static_cast<int>(1.5 * s)), cv::LINE_AA);
    y += static_cast<int>(24 * s);
  }
  return drawn;
}

}  // namespace horizonreg
