// SPDX-License-Identifier: MIT
// The inner ridges as a second cue (issue 13): where two poses fit the
// skyline almost equally well, the DEM's inner silhouettes (the paper's
// surface silhouettes S_s: nearer ridges standing against terrain farther
// behind) tell them apart. At the true pose they fall on edges of the photo
// (a dark slope over snow, a lit ridge over a shaded valley); at a pose
// elsewhere on the horizon they cross the image where it shows none of
// that shape. Measured on the real photos registered at their true
// positions: about 40-70% of the ridge points the true pose projects lie
// on an aligned edge, 20-50% of its best rival's (the share a textured
// glacier lends any line is about 30%). An orientation cue, not a
// position one: from 2 km beside a station the ridges line up as well, so
// a registration they decide is held to a stricter position check
// (PositionCheckOptions::ridges_decided).
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "camera/camera.h"
#include "horizon/horizon.h"
#include "match/register.h"

namespace horizonreg {

// The photo's edges as the check reads them: the gradient of its grey
// image smoothed over ~1 px per 1000 columns, and the mean gradient
// magnitude around each pixel (15 px per 1000 columns square).
struct PhotoEdges {
  cv::Mat gx, gy, local_mean;  // CV_32F, the photo's size
  int width() const { return gx.cols; }
  int height() const { return gx.rows; }
};
// `image` 8-bit BGR or grey. Throws InvalidArgument for an empty image.
PhotoEdges ComputePhotoEdges(const cv::Mat& image);

struct RidgeSupport {
  int points = 0;     // ridge points projected inside the image, below the skyline, with a direction
  int supported = 0;  // ... on an aligned edge
  double Share() const { return points > 0 ? static_cast<double>(supported) / points : 0.0; }
};

// How many of the inner ridge points (`ridges`, per bin of `horizon`, as
// ComputeRidges gives them) that `pose` and `k` project into the photo lie
// on one of its edges. A point counts where the line to the same ridge in
// the next bin (its distance within 10%) gives it a direction, it lies at
// least 4 px (per 1000 columns) below the projected horizon, and within 3
// px of it across the line the gradient across the line is at least twice
// the gradient along it and 1.5 times the local mean gradient magnitude.
// `edges` must be of k's size (else InvalidArgument).
RidgeSupport MeasureRidgeSupport(const PhotoEdges& edges, const HorizonProfile& horizon,
                                 const std::vector<std::vector<Ridge>>& ridges, const CameraPose& pose,
                                 const CameraIntrinsics& k);

struct RidgeCheck {
  RidgeSupport best;
  // The candidates that threatened the best (cost within the ambiguity
  // ratio, another solution) with their support, and which of them the
  // ridges rule out.
  struct Rival {
    PoseCandidate candidate;
    RidgeSupport support;
    bool ruled_out = false;
  };
  std::vector<Rival> rivals;
  std::vector<CameraPose> RuledOut() const;  // the poses of the rivals ruled out
};

// Whether the ridges rule `rival` out against `best`: each measured over at
// least kRidgeMinPoints points, and either the best's share is at least
// kRidgeMinBestShare and kRidgeMinShareRatio times the rival's, or it is at
// least kRidgeMinBestShareClear and kRidgeClearShareRatio times the
// rival's (a weaker best against a rival the photo shows almost none of:
// CG05_20050827_190000 without EXIF, best 0.43, its rivals 0.04-0.09,
// where the share a textured glacier lends any line is about 0.3).
inline constexpr double kRidgeMinBestShare = 0.45;
inline constexpr double kRidgeMinShareRatio = 1.4;
inline constexpr double kRidgeMinBestShareClear = 0.35;
inline constexpr double kRidgeClearShareRatio = 3.0;
inline constexpr int kRidgeMinPoints = 50;
bool RidgesRuleOut(const RidgeSupport& best, const RidgeSupport& rival);

// The ridge check of a registration refused as ambiguous (`reg`, its
// candidates): each candidate that is another solution (more than
// RegistrationOptions::kRuledOutDeg from the best in azimuth or pitch, and
// not among options.ruled_out_rivals already: an earlier round's) and
// costs less than min_ambiguity_ratio times the best's is ruled out where
// RidgesRuleOut(best's support, its support).
RidgeCheck CheckRidges(const PhotoEdges& edges, const HorizonProfile& horizon,
                       const std::vector<std::vector<Ridge>>& ridges, const Registration& reg,
                       const RegistrationOptions& options);

}  // namespace horizonreg
