// SPDX-License-Identifier: MIT
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>

#include "match/extrema.h"
#include "match/fit.h"
#include "match/hypothesis.h"
#include "match/register.h"
#include "util/angles.h"
#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(ExtremaOptions, DefaultsAreValid) { EXPECT_NO_THROW(ExtremaOptions{}.Check()); }
TEST(RegistrationOptions, DefaultsAreValid) { EXPECT_NO_THROW(RegistrationOptions{}.Check()); }

TEST(RegistrationOptions, CheckNamesTheField) {
  RegistrationOptions o;
  o.max_hfov_deg = 5.0;
  try {
    o.Check();
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("max_hfov_deg = 5"), std::string::npos) << e.what();
  }
}

TEST(RegistrationOptions, MisfitRatioIsAShareOfTheBestMisfit) {
  RegistrationOptions o;
  o.min_misfit_ratio = 1.5;
  EXPECT_THROW(o.Check(), InvalidArgument);
  o.min_misfit_ratio = -0.1;
  EXPECT_THROW(o.Check(), InvalidArgument);
}

TEST(FindExtrema, PeakAndDipWithTheirProminence) {
  //                          0  1  2  3  4  5  6  7  8
  const std::vector<double> v{0, 1, 5, 1, 2, 0, 3, 2, 2};
  const auto e = FindExtrema(v, false, {});
  ASSERT_EQ(e.size(), 5u);  // peaks at 2, 4, 6; dips at 3, 5
  EXPECT_TRUE(e[0].is_max);
  EXPECT_NEAR(e[0].value, 5.0, 1e-12);
  EXPECT_NEAR(e[0].prominence, 5.0, 1e-12);  // the run's ends bound it: max(0, 0)
  EXPECT_FALSE(e[1].is_max);
  EXPECT_NEAR(e[1].prominence, 1.0, 1e-12);  // dip at 3: up to 2 on its right
  EXPECT_NEAR(e[2].prominence, 1.0, 1e-12);  // peak 2 at 4: down to 1 on its left before the higher 5
  EXPECT_NEAR(e[4].prominence, 1.0, 1e-12);  // peak 3 at 6: down to 0 on the left, 2 on the right (run end)
}

TEST(FindExtrema, SubSamplePositionOfASymmetricPeak) {
  std::vector<double> v;
  for (int i = 0; i < 20; ++i) v.push_back(-std::pow(i - 9.3, 2));
  ExtremaOptions o;
  o.min_prominence = 1.0;
  const auto e = FindExtrema(v, false, o);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NEAR(e[0].position, 9.3, 1e-9);  // a parabola is found exactly
}

TEST(FindExtrema, CircularSignalWrapsAndNanSplitsRuns) {
  std::vector<double> v(360);
  for (int i = 0; i < 360; ++i) v[i] = std::cos(DegToRad(i));  // peak at 0, dip at 180
  auto e = FindExtrema(v, true, {});
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(e[0].position, 0.0, 1e-6);
  EXPECT_NEAR(e[0].prominence, 2.0, 1e-6);
  EXPECT_NEAR(e[1].position, 180.0, 1e-6);
  // Not circular: the peak at index 0 sits at the end of the run.
  e = FindExtrema(v, false, {});
  ASSERT_EQ(e.size(), 1u);
  EXPECT_FALSE(e[0].is_max);
  // A NaN gap next to the dip: the dip is no longer confirmed.
  v[181] = NAN;
  e = FindExtrema(v, false, {});
  EXPECT_TRUE(e.empty());
}

TEST(FindExtrema, MaxCountKeepsTheMostProminent) {
  const std::vector<double> v{0, 1, 0, 3, 0, 2, 0};
  ExtremaOptions o;
  o.max_count = 2;
  const auto e = FindExtrema(v, false, o);
  int peaks = 0;
  for (const auto& x : e)
    if (x.is_max) {
      ++peaks;
      EXPECT_GE(x.value, 2.0);
    }
  EXPECT_EQ(peaks, 2);
}

ImagePoint Project(const CameraPose& pose, double f, int w, int h, const HorizonPoint& p) {
  CameraIntrinsics k = CameraIntrinsics::FromHfov(w, h, 50.0);
  k.focal_px = f;
  const auto px = ProjectAzEl(CamFromEnu(pose), k, p.azimuth_deg, p.elevation_deg);
  return {px->x(), px->y()};
}

TEST(PaperHypothesis, Eq5And8AreExactForTheSphericalImage) {
  const double c = 1100.0, alpha_c = 358.0, cx = 512, cy = 341.5;  // C_x in pixels per radian
  const HorizonPoint h1{345.0, 0.0}, h2{9.0, 0.0};
  auto x_of = [&](const HorizonPoint& p) { return cx + c * std::sin(DegToRad(AngDiffDeg(p.azimuth_deg, alpha_c))); };
  const auto hyp = PaperHypothesisFromPairs({x_of(h1), cy}, {x_of(h2), cy}, h1, h2, cx, cy);
  ASSERT_TRUE(hyp);
  EXPECT_NEAR(AngDiffDeg(hyp->azimuth_deg, alpha_c), 0.0, 1e-9);
  EXPECT_NEAR(hyp->cx_px_per_deg, c * kPi / 180.0, 1e-9);
}

TEST(PaperHypothesis, Eq5ApproximatesAPinholeCamera) {
  const int w = 1024, h = 683;
  const double f = 1100.0;
  const CameraPose pose{358.0, 0.0, 0.0};  // across north
  const HorizonPoint h1{345.0, 0.0}, h2{9.0, 0.0};
  const auto p1 = Project(pose, f, w, h, h1), p2 = Project(pose, f, w, h, h2);
  const auto hyp = PaperHypothesisFromPairs(p1, p2, h1, h2, w / 2.0, h / 2.0);
  ASSERT_TRUE(hyp);
  EXPECT_NEAR(AngDiffDeg(hyp->azimuth_deg, pose.azimuth_deg), 0.0, 0.05);
  EXPECT_NEAR(hyp->cx_px_per_deg / (f * kPi / 180.0), 1.0, 0.03);  // tan against sin at +-13 deg
}

TEST(PaperHypothesis, Eq6And9GivePitchAndCy) {
  const int w = 1024, h = 683;
  const double f = 1500.0;
  const CameraPose pose{100.0, 2.0, 0.0};
  const HorizonPoint h1{95.0, 1.0}, h2{104.0, 4.0};
  const auto p1 = Project(pose, f, w, h, h1), p2 = Project(pose, f, w, h, h2);
  const auto hyp = PaperHypothesisFromPairs(p1, p2, h1, h2, w / 2.0, h / 2.0);
  ASSERT_TRUE(hyp);
  EXPECT_NEAR(hyp->pitch_deg, 2.0, 0.05);  // linearised: small error
  EXPECT_NEAR(hyp->cy_px_per_deg / (f * kPi / 180.0), 1.0, 0.02);
  EXPECT_NEAR(AngDiffDeg(hyp->azimuth_deg, pose.azimuth_deg), 0.0, 0.05);
}

TEST(PaperHypothesis, DegenerateInputIsRejected) {
  EXPECT_FALSE(PaperHypothesisFromPairs({100, 10}, {100, 20}, {1, 1}, {2, 2}, 512, 300));  // same column
  EXPECT_FALSE(PaperHypothesisFromPairs({100, 10}, {200, 20}, {2, 1}, {1, 2}, 512, 300));  // opposite order
}

TEST(TwoPointPose, RecoversAnyPoseAndFocalExactly) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> az(0, 360), pitch(-20, 20), roll(-25, 25), hfov(15, 100), u(0.05, 0.95);
  const int w = 1024, h = 683;
  int solved = 0;
  for (int i = 0; i < 200; ++i) {
    const CameraPose pose{az(rng), pitch(rng), roll(rng)};
    CameraIntrinsics k = CameraIntrinsics::FromHfov(w, h, hfov(rng));
    const Eigen::Matrix3d m = CamFromEnu(pose);
    const Eigen::Vector2d q1(u(rng) * w, u(rng) * h), q2(u(rng) * w, u(rng) * h);
    if ((q1 - q2).norm() < 50) continue;
    const AzEl a1 = AzElFromEnu(UnprojectToEnu(m, k, q1)), a2 = AzElFromEnu(UnprojectToEnu(m, k, q2));
    const auto all = TwoPointPoses({q1.x(), q1.y()}, {q2.x(), q2.y()}, {a1.azimuth_deg, a1.elevation_deg},
                                   {a2.azimuth_deg, a2.elevation_deg}, k.cx_px, k.cy_px, 100.0, 20000.0);
    const auto s = std::min_element(all.begin(), all.end(), [&](const PoseHypothesis& a, const PoseHypothesis& b) {
      return std::abs(a.focal_px - k.focal_px) < std::abs(b.focal_px - k.focal_px);
    });
    ASSERT_NE(s, all.end());
    ++solved;
    EXPECT_NEAR(s->focal_px / k.focal_px, 1.0, 1e-5);
    EXPECT_NEAR(AngDiffDeg(s->pose.azimuth_deg, pose.azimuth_deg), 0.0, 1e-4);
    EXPECT_NEAR(s->pose.pitch_deg, pose.pitch_deg, 1e-4);
    EXPECT_NEAR(s->pose.roll_deg, pose.roll_deg, 1e-4);
  }
  EXPECT_GT(solved, 150);
}

TEST(TwoPointPose, FocalOutsideTheRangeGivesNothing) {
  const int w = 1000, h = 600;
  const CameraPose pose{10, 0, 0};
  const HorizonPoint h1{5, 1}, h2{15, 2};
  const auto p1 = Project(pose, 2000, w, h, h1), p2 = Project(pose, 2000, w, h, h2);
  EXPECT_EQ(TwoPointPoses(p1, p2, h1, h2, w / 2.0, h / 2.0, 1000, 3000).size(), 1u);
  EXPECT_TRUE(TwoPointPoses(p1, p2, h1, h2, w / 2.0, h / 2.0, 100, 1500).empty());
}

// A mountain horizon without repeats: a sum of incommensurate waves.
HorizonProfile SyntheticHorizon(double step, bool flat = false, int period_count = 0) {
  HorizonProfile p;
  p.azimuth_step_deg = step;
  const int n = static_cast<int>(std::lround(360.0 / step));
  for (int i = 0; i < n; ++i) {
    const double a = DegToRad(i * step);
    double e = 1.0;
    if (period_count > 0)
      e += 2.0 * std::sin(period_count * a);
    else if (!flat)
      e += 1.8 * std::sin(3 * a + 0.3) + 0.9 * std::sin(7 * a + 1.0) + 0.5 * std::sin(13 * a + 2.0) +
           0.25 * std::sin(29 * a + 0.5) + 0.12 * std::sin(61 * a + 1.3);
    p.elevation_deg.push_back(e);
  }
  p.distance_m.assign(n, 10000.0);
  p.lat_deg.assign(n, 0.0);
  p.lon_deg.assign(n, 0.0);
  p.height_m.assign(n, 0.0);
  return p;
}

Skyline SkylineOf(const HorizonProfile& p, const CameraPose& pose, const CameraIntrinsics& k) {
  Skyline s;
  s.width = k.width;
  s.height = k.height;
  s.y = ProjectedHorizonRows(p, pose, k);
  for (double& y : s.y)
    if (y < 0 || y >= k.height) y = NAN;
  s.confidence.assign(k.width, 1.0);
  return s;
}

TEST(Register, RecoversASyntheticPoseWithoutPriors) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  for (const auto& [pose, hfov] : std::vector<std::pair<CameraPose, double>>{
           {{123.4, 1.5, 0.0}, 40.0}, {{300.2, -2.0, 3.0}, 60.0}, {{12.0, 0.5, -2.5}, 25.0}}) {
    const auto k = CameraIntrinsics::FromHfov(1024, 683, hfov);
    const Registration r = Register(SkylineOf(p, pose, k), p, {});
    ASSERT_TRUE(r.registered) << r.message;
    EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.01);
    EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.01);
    EXPECT_NEAR(r.pose.roll_deg, pose.roll_deg, 0.02);
    EXPECT_NEAR(r.focal_px / k.focal_px, 1.0, 0.002);
    EXPECT_LT(r.rms_px, 0.2);
    EXPECT_GT(r.hypotheses, 0);
  }
}

// A narrow window of opening angles (a known --hfov) is a constraint on the
// answer, not only on the search: a skyline that fits only 1.8% below the
// window (inside the 5% the candidates may stray) is no registration. So is
// a wide window (the EXIF's +-10%), with no slack: any opening angle inside
// it is kept, one past its edge is not.
TEST(Register, AKnownOpeningAngleIsKept) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{300.2, -2.0, 3.0};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 60.0);
  RegistrationOptions known;
  known.min_hfov_deg = 60.0 * 0.97, known.max_hfov_deg = 60.0 * 1.03;
  ASSERT_TRUE(known.NarrowHfovWindow());
  const Registration kept = Register(SkylineOf(p, pose, k), p, known);
  EXPECT_TRUE(kept.registered) << kept.message;
  RegistrationOptions off = known;
  off.min_hfov_deg = 63.0 * 0.97, off.max_hfov_deg = 63.0 * 1.03;
  const Registration refused = Register(SkylineOf(p, pose, k), p, off);
  EXPECT_FALSE(refused.registered);
  EXPECT_NE(refused.message.find("outside the one given"), std::string::npos) << refused.message;
  EXPECT_NEAR(refused.hfov_deg, 60.0, 0.1);  // the fit itself found the truth
  EXPECT_FALSE(off.KeepsKnownHfov(60.0));
  EXPECT_TRUE(off.KeepsKnownHfov(61.0));
  RegistrationOptions wide;
  wide.min_hfov_deg = 35.0, wide.max_hfov_deg = 50.0;
  ASSERT_FALSE(wide.NarrowHfovWindow());
  EXPECT_TRUE(wide.KeepsKnownHfov(35.0));
  EXPECT_TRUE(wide.KeepsKnownHfov(50.0));
  EXPECT_FALSE(wide.KeepsKnownHfov(34.9));
  EXPECT_FALSE(wide.KeepsKnownHfov(50.1));
  // The truth 3% past a wide window's upper edge: inside the 5% a candidate
  // may stray, so the fit finds it, and refuses it.
  RegistrationOptions below = wide;
  below.min_hfov_deg = 0.8 * 60.0 / 1.03, below.max_hfov_deg = 60.0 / 1.03;
  ASSERT_FALSE(below.NarrowHfovWindow());
  const Registration past = Register(SkylineOf(p, pose, k), p, below);
  EXPECT_FALSE(past.registered);
  EXPECT_NE(past.message.find("outside the one given"), std::string::npos) << past.message;
  RegistrationOptions around = wide;
  around.min_hfov_deg = 60.0 / 1.1, around.max_hfov_deg = 60.0 * 1.1;
  const Registration inside = Register(SkylineOf(p, pose, k), p, around);
  EXPECT_TRUE(inside.registered) << inside.message;
}

// A skyline that only a lens bent past k1's box (kK1Bound) lays on the
// horizon is no registration: the fit runs k1 to the box's end, which no
// camera's lens reaches (a wrong place's horizon is what bends it so). A
// lens inside the box is fitted and registered.
TEST(Register, ALensBentToTheEndOfItsRangeIsRefused) {
  const HorizonProfile p = SyntheticHorizon(0.1);
  const CameraPose pose{123.4, 1.5, 0.0};
  CameraIntrinsics k = CameraIntrinsics::FromHfov(1024, 683, 60.0);
  k.distortion = LensDistortion::Radial(-0.1);
  const Registration kept = Register(SkylineOf(p, pose, k), p, {});
  ASSERT_TRUE(kept.registered) << kept.message;
  ASSERT_TRUE(kept.distortion_estimated);
  EXPECT_NEAR(kept.intrinsics.distortion.k()[0], -0.1, 0.02);
  k.distortion = LensDistortion::Radial(0.8);
  const Registration bent = Register(SkylineOf(p, pose, k), p, {});
  EXPECT_FALSE(bent.registered);
  EXPECT_NE(bent.message.find("lens bent to the end of its range"), std::string::npos) << bent.message;
}

// A crop of a wide view (the camera's centre 150 px right of the image's):
// registered as centred, the centre ray is off; RefinePrincipalColumn finds
// the camera's centre and the centre ray. Without a range it does nothing.
TEST(RefinePrincipalColumn, FindsTheCentreOfACroppedCamera) {
  const HorizonProfile p = SyntheticHorizon(0.1);
  CameraIntrinsics k = CameraIntrinsics::FromHfov(800, 600, 55.0);
  k.cx_px += 150.0;
  const CameraPose axis{123.4, 1.0, 1.5};
  const CameraPose truth = CenterRayPose(axis, k);
  const Skyline sky = SkylineOf(p, axis, k);
  RegistrationOptions o;
  const Registration centred = Register(sky, p, o);
  ASSERT_TRUE(centred.registered) << centred.message;
  const double centred_error = std::abs(AngDiffDeg(centred.center_ray.azimuth_deg, truth.azimuth_deg));
  EXPECT_GT(centred_error, 0.1);
  EXPECT_EQ(RefinePrincipalColumn(sky, p, centred, o).center_ray.azimuth_deg, centred.center_ray.azimuth_deg);
  o.principal_point_range = 0.25;
  const Registration r = RefinePrincipalColumn(sky, p, centred, o);
  EXPECT_TRUE(r.registered);
  EXPECT_NEAR(r.intrinsics.cx_px, k.cx_px, 10.0);
  EXPECT_LT(std::abs(AngDiffDeg(r.center_ray.azimuth_deg, truth.azimuth_deg)), 0.2 * centred_error);
  EXPECT_NEAR(r.center_ray.pitch_deg, truth.pitch_deg, 0.03);
}

// The ambiguity is taken against another solution: a candidate the quick
// refinement left a few degrees down the best's slope (here 4-5 deg off in
// azimuth, on a noisy skyline with a misread stretch) is refined again and,
// converging onto the best, is no rival. The rival reported is a minimum of
// its own: refined from there it stays apart from the best.
TEST(Register, TheRivalIsAMinimumOfItsOwn) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  for (const int seed : {24, 36}) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const CameraPose pose{360 * u(rng), -3 + 6 * u(rng), -3 + 6 * u(rng)};
    const double hfov = 30 + 30 * u(rng);
    const auto k = CameraIntrinsics::FromHfov(1024, 683, hfov);
    Skyline s = SkylineOf(p, pose, k);
    std::normal_distribution<double> noise(0.0, 1.5);
    for (double& y : s.y) y += noise(rng);
    const int a = static_cast<int>(u(rng) * 600);
    for (int c = a; c < a + 300; ++c) s.y[c] += 6.0 * std::sin(c / 20.0);  // a misread stretch
    RegistrationOptions o;
    o.min_hfov_deg = 0.8 * hfov, o.max_hfov_deg = 1.2 * hfov;
    const Registration r = Register(s, p, o);
    ASSERT_TRUE(r.registered) << seed << ": " << r.message;
    EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.5) << seed;
    ASSERT_TRUE(r.rival) << seed;
    const Registration from_rival = RefinePose(s, p, r.rival->pose, r.rival->focal_px, false, o, 12.0);
    EXPECT_GT(std::abs(AngDiffDeg(from_rival.pose.azimuth_deg, r.candidates[0].pose.azimuth_deg)), 1.0)
        << seed << ": the rival at " << r.rival->pose.azimuth_deg << " deg converges onto the best";
  }
}

TEST(Register, SurvivesNoiseAndAnOccluderSpike) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{200.0, 0.8, 1.2};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 45.0);
  Skyline s = SkylineOf(p, pose, k);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.7);
  for (double& y : s.y) y += noise(rng);
  for (int c = 600; c < 630; ++c) s.y[c] -= 80.0;  // a tree the extractor did not flag
  const Registration r = Register(s, p, {});
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.03);
  EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.03);
  EXPECT_GT(r.azimuth_sigma_deg, 0.0);
  EXPECT_LT(r.azimuth_sigma_deg, 0.05);
}

// Over 40% of the columns the skyline's y lies on a far ridge 12 px above
// the DEM's horizon, with the clearer edge on the horizon kept in y_alt:
// the matching reads y_alt there, and the pose registers with its inliers
// whole; the raised boundary alone misses in those columns.
TEST(Register, TheMatchingReadsTheClearerEdgeUnderARaisedRidge) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{200.0, 0.8, 1.2};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 45.0);
  Skyline s = SkylineOf(p, pose, k);
  s.y_alt.assign(s.width, NAN);
  for (int c = 100; c < 510; ++c) s.y_alt[c] = s.y[c], s.y[c] -= 12.0;
  const Registration r = Register(s, p, {});
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.01);
  EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.01);
  EXPECT_GT(r.inlier_fraction, 0.95);
  // A boundary off the horizon in those columns, read alone: they miss.
  for (int c = 100; c < 510; ++c) s.y[c] = s.y_alt[c] + 12.0;
  s.y_alt.clear();
  EXPECT_LT(Register(s, p, {}).inlier_fraction, 0.8);
}

// Haze over 43% of the range: the skyline there reads the sky 40 px down
// (terrain taken for sky). The pose is refused, and the misses are counted
// on their side of the DEM horizon, which the message names; pushed up
// instead (a cloud bank read as terrain), they lie above it.
TEST(Register, TheMissesAreCountedByTheirSideOfTheDemHorizon) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{200.0, 0.8, 1.2};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 45.0);
  const Skyline clear = SkylineOf(p, pose, k);
  Skyline s = clear;
  for (int c = 580; c < 1024; ++c) s.y[c] += 40.0;
  const Registration below = Register(s, p, {});
  EXPECT_FALSE(below.registered);
  EXPECT_GT(below.outliers_below, 3 * std::max(1, below.outliers_above)) << below.message;
  EXPECT_NE(below.message.find("lie below it"), std::string::npos) << below.message;
  s = clear;
  for (int c = 580; c < 1024; ++c) s.y[c] -= 40.0;
  const Registration above = Register(s, p, {});
  EXPECT_FALSE(above.registered);
  EXPECT_GT(above.outliers_above, 3 * std::max(1, above.outliers_below)) << above.message;
  EXPECT_NE(above.message.find("lie above it"), std::string::npos) << above.message;
  // The clear skyline: registered, no misses either side.
  const Registration r = Register(clear, p, {});
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_EQ(r.outliers_below + r.outliers_above, 0);
}

// A hut's gable in the foreground over 37% of the width, from the frame's
// left edge, its chimney unread: the sky's edge runs 20-77 px above the
// horizon it hides. Those misses rise out of the fitted skyline and do not
// count against the pose, which registers. A raise the same size that
// meets misses below instead of the fitted skyline (a wrong shape, not a
// thing in front) still counts.
TEST(Register, AThingInFrontHidesTheHorizonWithoutRefutingThePose) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{200.0, 0.8, 1.2};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 45.0);
  const Skyline clear = SkylineOf(p, pose, k);
  Skyline s = clear;
  double top = INFINITY;
  for (int c = 0; c < 380; ++c) top = std::min(top, s.y[c]);
  for (int c = 0; c < 380; ++c) s.y[c] = top - 20.0 - 0.3 * (190.0 - std::abs(c - 190.0));
  for (int c = 250; c < 270; ++c) s.y[c] = NAN;
  const Registration r = Register(s, p, {});
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.03);
  EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.03);
  EXPECT_GT(r.hidden_columns, 300);
  EXPECT_LT(r.inlier_fraction, RegistrationOptions{}.min_inlier_fraction);
  EXPECT_GT(r.unhidden_inlier_fraction, 0.95);
  // The same raise with the skyline beside it read 40 px too low (terrain
  // taken for sky): no run rises out of the fitted skyline, nothing is hidden.
  for (int c = 380; c < 460; ++c) s.y[c] += 40.0;
  const Registration w = Register(s, p, {});
  EXPECT_FALSE(w.registered) << w.message;
  EXPECT_EQ(w.hidden_columns, 0);
  // Hidden, but too little of the rest fits: refused, and the message says so.
  for (int c = 380; c < 460; ++c) s.y[c] -= 40.0;
  for (int c = 600; c < 760; ++c) s.y[c] += 40.0;
  const Registration h = Register(s, p, {});
  EXPECT_FALSE(h.registered) << h.message;
  EXPECT_NE(h.message.find("hidden by something in front"), std::string::npos) << h.message;
}

// The hypotheses and candidates are shared out among threads; any count
// gives the same answer, to the bit.
TEST(Register, SameResultForAnyThreadCount) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 45.0);
  Skyline s = SkylineOf(p, {200.0, 0.8, 1.2}, k);
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.7);
  for (double& y : s.y) y += noise(rng);
  RegistrationOptions one;
  one.num_threads = 1;
  const Registration a = Register(s, p, one);
  for (int threads : {2, 3, 7}) {
    RegistrationOptions o;
    o.num_threads = threads;
    const Registration b = Register(s, p, o);
    EXPECT_EQ(a.registered, b.registered) << threads;
    EXPECT_EQ(a.hypotheses, b.hypotheses) << threads;
    EXPECT_EQ(a.pose.azimuth_deg, b.pose.azimuth_deg) << threads;
    EXPECT_EQ(a.pose.pitch_deg, b.pose.pitch_deg) << threads;
    EXPECT_EQ(a.pose.roll_deg, b.pose.roll_deg) << threads;
    EXPECT_EQ(a.focal_px, b.focal_px) << threads;
    EXPECT_EQ(a.ambiguity_ratio, b.ambiguity_ratio) << threads;
  }
  RegistrationOptions none;
  none.num_threads = 0;
  EXPECT_THROW(none.Check(), InvalidArgument);
}

// Haze drops columns of low contrast: short gaps (up to 3% of the width)
// are bridged for finding peaks and dips, so a skyline cut into 20-column
// runs still registers, and the gaps stay gaps in the fit.
TEST(Register, ShortGapsInTheSkylineDoNotHideItsPeaks) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{300.2, -2.0, 3.0};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 30.0);
  Skyline s = SkylineOf(p, pose, k);
  for (int c = 0; c < s.width; ++c)
    if (c % 45 >= 20) s.y[c] = NAN, s.confidence[c] = 0.0;
  const Registration r = Register(s, p, {});
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.02);
  EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.02);
  // The best pose fits more closely than any distinct alternative.
  EXPECT_GE(r.second_misfit, RegistrationOptions{}.min_misfit_ratio * r.misfit);
}

// A ridge rising in two steps seen over 40% of the frame, the rest hidden
// (behind near trees): no peak or dip to pair. With the opening angle
// known (or a compass bounding the azimuths), the azimuth scan finds the
// pose; without the scan, or in a wide window with no compass, nothing.
// The horizon elevation(azimuth) (degrees, every 0.25 deg) and its skyline
// seen from kPlainViewPose at an opening angle of 50 deg over the left 410
// of 1024 columns, the rest hidden (behind near trees).
const CameraPose kPlainViewPose{116.5, -4.0, 4.0};
template <typename Elevation>
std::pair<HorizonProfile, Skyline> PlainView(const Elevation& elevation) {
  HorizonProfile p = SyntheticHorizon(0.25, true);
  for (int i = 0; i < p.size(); ++i) p.elevation_deg[i] = elevation(p.AzimuthDeg(i));
  Skyline s = SkylineOf(p, kPlainViewPose, CameraIntrinsics::FromHfov(1024, 683, 50.0));
  for (int c = 410; c < s.width; ++c) s.y[c] = NAN, s.confidence[c] = 0.0;
  return {std::move(p), std::move(s)};
}

TEST(Register, TheAzimuthScanRegistersAPlainSkyline) {
  const auto [p, s] = PlainView([](double az) {  // and two cliffs rising to the east in view: no peak, no dip
    const double a = DegToRad(az);
    return 1.0 + 1.8 * std::sin(3 * a + 0.3) + 0.9 * std::sin(7 * a + 1.0) +
           0.5 / (1.0 + std::exp(-(az - 97.0) / 0.3)) + 0.3 / (1.0 + std::exp(-(az - 106.0) / 0.3));
  });
  const CameraPose pose = kPlainViewPose;
  RegistrationOptions known;
  known.min_hfov_deg = 50.0 * 0.97, known.max_hfov_deg = 50.0 * 1.03;
  const Registration r = Register(s, p, known);
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_GT(r.scanned_hypotheses, 0);
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.02);
  EXPECT_NEAR(r.pose.pitch_deg, pose.pitch_deg, 0.02);
  EXPECT_NEAR(r.pose.roll_deg, pose.roll_deg, 0.05);
  RegistrationOptions compass;  // any opening angle, the azimuth within 3 x 10 deg
  compass.prior.compass_deg = 110.0;
  compass.prior.compass_sigma_deg = 10.0;
  const Registration c = Register(s, p, compass);
  ASSERT_TRUE(c.registered) << c.message;
  EXPECT_NEAR(AngDiffDeg(c.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.02);
  EXPECT_NEAR(c.hfov_deg, 50.0, 0.2);
  RegistrationOptions off = known;
  off.scan_plain_skylines = false;
  const Registration without = Register(s, p, off);
  EXPECT_FALSE(without.registered);
  EXPECT_EQ(without.scanned_hypotheses, 0);
  const Registration wide = Register(s, p, {});
  EXPECT_FALSE(wide.registered && std::abs(AngDiffDeg(wide.pose.azimuth_deg, pose.azimuth_deg)) > 1.0);
  EXPECT_EQ(wide.scanned_hypotheses, 0);
}

// A skyline with no peak or dip (one cliff rising over a level rough
// ridge: a texture of 1 px every 0.7 deg) seen through a window of opening
// angles +-12% wide: the scan runs alone, a dozen focal lengths, and its
// minima near the cliff (one every 0.7 deg at each focal length, all
// fitting but for the few columns on the cliff) outnumber the 32 kept. Kept
// as they came, they were all one solution: the search had no alternative
// to measure the ambiguity against and called the pose unambiguous (a plain
// strip of a real photo, given a position 2 km off, registered 95.6 deg off
// so). With up to 32 distinct minima kept besides, the level ridge
// elsewhere is the rival, and the pose is still found (distinct minima
// alone dropped the start nearest to it).
TEST(Register, TheAzimuthScanKeepsDistinctPoses) {
  const auto [p, s] = PlainView([](double az) {
    return 1.0 + 0.5 / (1.0 + std::exp(-(az - 97.0) / 0.3)) + 0.06 * std::sin(2.0 * kPi * az / 0.7);
  });
  const CameraPose pose = kPlainViewPose;
  RegistrationOptions window;
  window.min_hfov_deg = 50.0 * 0.88, window.max_hfov_deg = 50.0 * 1.12;
  const Registration r = Register(s, p, window);
  EXPECT_LE(r.image_extrema, 1);
  EXPECT_GT(r.scanned_hypotheses, 0);
  ASSERT_FALSE(r.candidates.empty()) << r.message;
  const PoseCandidate& best = r.candidates[0];
  const bool other = std::any_of(r.candidates.begin() + 1, r.candidates.end(), [&](const PoseCandidate& c) {
    return std::abs(AngDiffDeg(c.pose.azimuth_deg, best.pose.azimuth_deg)) > 5.0;
  });
  EXPECT_TRUE(other) << r.candidates.size() << " candidates, all within 5 deg of the best";
  EXPECT_TRUE(std::isfinite(r.ambiguity_ratio)) << r.message;
  EXPECT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, pose.azimuth_deg), 0.0, 0.05);
}

TEST(Register, FlatOrRepeatingHorizonGivesNoMatch) {
  const CameraPose pose{80.0, 0.0, 0.0};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 40.0);
  const HorizonProfile flat = SyntheticHorizon(0.25, true);
  EXPECT_FALSE(Register(SkylineOf(flat, pose, k), flat, {}).registered);
  const HorizonProfile periodic = SyntheticHorizon(0.25, false, 12);  // 12 identical mountains
  const Registration r = Register(SkylineOf(periodic, pose, k), periodic, {});
  EXPECT_FALSE(r.registered) << r.message;
}

TEST(Register, ACompassPriorResolvesARepeatingHorizon) {
  const CameraPose pose{80.0, 0.0, 0.0};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 40.0);
  const HorizonProfile periodic = SyntheticHorizon(0.25, false, 12);  // peaks every 30 deg
  RegistrationOptions o;
  o.prior.compass_deg = 86.0;
  o.prior.compass_sigma_deg = 4.0;
  o.min_hfov_deg = 35.0;
  o.max_hfov_deg = 45.0;
  const Registration r = Register(SkylineOf(periodic, pose, k), periodic, o);
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, 80.0), 0.0, 0.01);
}

// Rivals an image cue has told apart (RegistrationOptions::ruled_out_rivals,
// the pipeline's inner ridges) are no alternative: twelve mountains that
// differ by 2% in height leave the search ambiguous; with the
// other eleven ruled out, it registers, and ruling out the truth's
// neighbours only (not all) leaves it ambiguous.
TEST(Register, RuledOutRivalsAreNoAlternative) {
  HorizonProfile p = SyntheticHorizon(0.25, false, 12);  // peaks every 30 deg
  for (int i = 0; i < p.size(); ++i)  // each mountain's height a little different
    p.elevation_deg[i] = 1.0 + (p.elevation_deg[i] - 1.0) * (1.0 + 0.02 * std::sin(DegToRad(p.AzimuthDeg(i)) + 0.7));
  const CameraPose pose{80.0, 0.0, 0.0};
  const auto k = CameraIntrinsics::FromHfov(1024, 683, 40.0);
  RegistrationOptions o;
  o.min_hfov_deg = 35.0;
  o.max_hfov_deg = 45.0;
  const Skyline s = SkylineOf(p, pose, k);
  const Registration plain = Register(s, p, o);
  ASSERT_FALSE(plain.registered) << plain.message;
  ASSERT_TRUE(plain.rival);
  for (int j = 1; j < 12; ++j) o.ruled_out_rivals.push_back({WrapAzimuthDeg(80.0 + 30.0 * j), 0.0, 0.0});
  const Registration r = Register(s, p, o);
  ASSERT_TRUE(r.registered) << r.message;
  EXPECT_NEAR(AngDiffDeg(r.pose.azimuth_deg, 80.0), 0.0, 0.01);
  o.ruled_out_rivals.resize(2);  // 110 and 140 deg: the other nine stay rivals
  EXPECT_FALSE(Register(s, p, o).registered);
}

TEST(Register, EmptySkylineGivesNoMatchNotAnError) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  Skyline s;
  s.width = 640;
  s.height = 480;
  s.y.assign(640, NAN);
  s.confidence.assign(640, 0.0);
  const Registration r = Register(s, p, {});
  EXPECT_FALSE(r.registered);
  EXPECT_FALSE(r.message.empty());
}

// The paper's correction (eq. 11-14) finds each column's closest point on
// the DEM silhouette among the segments that reach its window: on steep
// slopes under a strong roll the silhouette turns back on itself in the
// image, and the segments looked at must still be all that reach it. At the
// true pose every column lies on the silhouette (distances ~0) and the
// correction keeps the pose; unrolled, from 0.2 deg off it comes back (its
// linear model of eq. 11-12 is not made for a strong roll).
TEST(CorrectLinear, FindsTheSilhouetteUnderAStrongRollOnSteepSlopes) {
  using namespace match_detail;
  const HorizonProfile p = SyntheticHorizon(0.05, false, 80);  // slopes up to 70 deg
  const DemErrorModel model;
  const HorizonLookup lookup(p, model);
  for (const double roll : {0.0, 50.0, -65.0, 75.0}) {
    const CameraPose pose{200.0, 1.0, roll};
    const auto k = CameraIntrinsics::FromHfov(800, 600, 40.0);
    const Skyline sky = SkylineOf(p, pose, k);
    const ImageFrame frame(sky, std::nullopt);
    const Scorer scorer(lookup, model, 1.0, k.height, 0.25);
    const std::vector<Column> cols = VisibleColumns(sky, frame);
    ASSERT_GT(cols.size(), 150u) << roll;
    const Pose4 truth = Pose4::From(pose, k.focal_px);
    const PaperCorrection at = CorrectLinear(scorer, cols, truth, k.width, 2.0);
    ASSERT_TRUE(std::isfinite(at.ex_px) && std::isfinite(at.ey_px)) << roll;
    EXPECT_EQ(at.matched, static_cast<int>(cols.size())) << roll;
    EXPECT_LT(at.ex_px, 0.1) << roll;
    EXPECT_LT(at.ey_px, 0.1) << roll;
    EXPECT_NEAR(RadToDeg(at.pose.yaw - truth.yaw), 0.0, 0.005) << roll;
    if (roll != 0.0) continue;
    Pose4 off = truth;
    off.yaw += DegToRad(0.2);
    const PaperCorrection back = CorrectLinear(scorer, cols, off, k.width, 2.0);
    EXPECT_LT(std::abs(RadToDeg(back.pose.yaw - truth.yaw)), 0.1) << roll;
  }
}

TEST(HorizonDistancePx, PositiveBelowTheSilhouette) {
  const HorizonProfile p = SyntheticHorizon(0.25);
  const CameraPose pose{50.0, 1.0, 0.0};
  const auto k = CameraIntrinsics::FromHfov(800, 600, 50.0);
  const auto rows = ProjectedHorizonRows(p, pose, k);
  EXPECT_NEAR(HorizonDistancePx(p, pose, k, 400.5, rows[400]), 0.0, 1e-3);
  EXPECT_GT(HorizonDistancePx(p, pose, k, 400.5, rows[400] + 5), 2.0);
  EXPECT_LT(HorizonDistancePx(p, pose, k, 400.5, rows[400] - 5), -2.0);
}

}  // namespace
}  // namespace horizonreg
