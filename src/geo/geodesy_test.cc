// SPDX-License-Identifier: MIT
#include "geo/geodesy.h"

#include <gtest/gtest.h>

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <random>

#include "util/errors.h"

namespace horizonreg {
namespace {

// Golden values: ECEF of known points (WGS84), from the definition.
TEST(EcefFromGeodetic, MatchesKnownValues) {
  Eigen::Vector3d equator = EcefFromGeodetic({0.0, 0.0, 0.0});
  EXPECT_NEAR(equator.x(), kWgs84A, 1e-6);
  EXPECT_NEAR(equator.y(), 0.0, 1e-6);
  EXPECT_NEAR(equator.z(), 0.0, 1e-6);
  Eigen::Vector3d pole = EcefFromGeodetic({90.0, 0.0, 0.0});
  EXPECT_NEAR(pole.z(), kWgs84A * (1.0 - kWgs84F), 1e-6);  // semi-minor axis 6356752.314245
  EXPECT_NEAR(pole.z(), 6356752.314245, 1e-5);
  Eigen::Vector3d east = EcefFromGeodetic({0.0, 90.0, 100.0});
  EXPECT_NEAR(east.y(), kWgs84A + 100.0, 1e-6);
}

TEST(EcefFromGeodetic, AgreesWithGeographicLibAtRandomPoints) {
  const GeographicLib::Geocentric earth(kWgs84A, kWgs84F);
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> lat(-90, 90), lon(-180, 180), h(-500, 9000);
  for (int i = 0; i < 1000; ++i) {
    GeodeticPoint p{lat(rng), lon(rng), h(rng)};
    Eigen::Vector3d ours = EcefFromGeodetic(p);
    double x, y, z;
    earth.Forward(p.lat_deg, p.lon_deg, p.height_m, x, y, z);
    EXPECT_NEAR((ours - Eigen::Vector3d(x, y, z)).norm(), 0.0, 1e-6);
  }
}

TEST(LocalFrame, GeodeticEnuGeodeticRoundTrips) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lat(-89, 89), lon(-180, 180), d(-0.9, 0.9), h(-400, 8000);
  for (int i = 0; i < 500; ++i) {
    GeodeticPoint o{lat(rng), lon(rng), h(rng)};
    LocalFrame frame(o);
    GeodeticPoint p{o.lat_deg + d(rng), o.lon_deg + d(rng), h(rng)};
    if (std::abs(p.lat_deg) > 90) continue;
    GeodeticPoint back = frame.GeodeticFromEnu(frame.EnuFromGeodetic(p));
    EXPECT_NEAR(back.lat_deg, p.lat_deg, 1e-10);
    EXPECT_NEAR(AngDiffDeg(back.lon_deg, p.lon_deg), 0.0, 1e-10);
    EXPECT_NEAR(back.height_m, p.height_m, 1e-6);
  }
}

TEST(LocalFrame, AgreesWithGeographicLibLocalCartesian) {
  GeodeticPoint o{46.85, -121.76, 1600.0};
  LocalFrame frame(o);
  GeographicLib::LocalCartesian lc(o.lat_deg, o.lon_deg, o.height_m);
  for (double dlat = -0.8; dlat <= 0.8; dlat += 0.2) {
    for (double dlon = -1.0; dlon <= 1.0; dlon += 0.25) {
      double x, y, z;
      lc.Forward(o.lat_deg + dlat, o.lon_deg + dlon, 2000.0, x, y, z);
      Eigen::Vector3d enu = frame.EnuFromGeodetic({o.lat_deg + dlat, o.lon_deg + dlon, 2000.0});
      EXPECT_NEAR((enu - Eigen::Vector3d(x, y, z)).norm(), 0.0, 1e-6);
    }
  }
}

TEST(LocalFrame, FarPointDropsBelowTangentPlaneByEarthCurvature) {
  // A point 50 km due north at the same height lies d^2/(2R') below the
  // tangent plane, R' the meridional radius of curvature (~6.37e6 m at 45 deg).
  LocalFrame frame({45.0, 7.0, 0.0});
  GeographicLib::LocalCartesian lc(45.0, 7.0, 0.0);
  double x, y, z;
  lc.Forward(45.0 + 50000.0 / 111132.0, 7.0, 0.0, x, y, z);
  Eigen::Vector3d enu = frame.EnuFromGeodetic({45.0 + 50000.0 / 111132.0, 7.0, 0.0});
  EXPECT_NEAR(enu.z(), z, 1e-6);
  EXPECT_NEAR(enu.z(), -enu.y() * enu.y() / (2.0 * 6367000.0), 1.0);
  EXPECT_NEAR(AngDiffDeg(AzElFromEnu(enu).azimuth_deg, 0.0), 0.0, 1e-9);
}

TEST(LocalFrame, AzimuthIsClockwiseFromNorth) {
  LocalFrame frame({10.0, 20.0, 0.0});
  EXPECT_NEAR(AzElFromEnu(frame.EnuFromGeodetic({10.0, 20.01, 0.0})).azimuth_deg, 90.0, 1e-3);
  EXPECT_NEAR(AzElFromEnu(frame.EnuFromGeodetic({9.99, 20.0, 0.0})).azimuth_deg, 180.0, 1e-9);
  EXPECT_NEAR(AzElFromEnu(frame.EnuFromGeodetic({10.0, 19.99, 0.0})).azimuth_deg, 270.0, 1e-3);
}

TEST(LocalFrame, AntimeridianIsContinuous) {
  LocalFrame frame({-17.0, 179.999, 0.0});
  Eigen::Vector3d enu = frame.EnuFromGeodetic({-17.0, -179.999, 0.0});
  EXPECT_NEAR(enu.x(), 2 * 0.001 * 111319.49 * std::cos(DegToRad(17.0)), 0.5);
}

TEST(LocalFrame, RejectsInvalidOrigin) {
  EXPECT_THROW(LocalFrame({91.0, 0.0, 0.0}), InvalidArgument);
  EXPECT_THROW(LocalFrame({NAN, 0.0, 0.0}), InvalidArgument);
  EXPECT_THROW(LocalFrame({0.0, INFINITY, 0.0}), InvalidArgument);
}

TEST(RefractionLiftM, MatchesFormulaAndZeroForK0) {
  EXPECT_DOUBLE_EQ(RefractionLiftM(50000.0, 0.0), 0.0);
  EXPECT_NEAR(RefractionLiftM(50000.0, 0.13), 0.13 * 2.5e9 / (2 * 6371000.0), 1e-9);  // 25.5 m
}

}  // namespace
}  // namespace horizonreg
