// SPDX-License-Identifier: MIT
#include "util/angles.h"

#include <gtest/gtest.h>

#include "util/errors.h"

namespace horizonreg {
namespace {

TEST(WrapAzimuthDeg, WrapsIntoHalfOpenRange) {
  EXPECT_DOUBLE_EQ(WrapAzimuthDeg(360.0), 0.0);
  EXPECT_DOUBLE_EQ(WrapAzimuthDeg(-90.0), 270.0);
  EXPECT_DOUBLE_EQ(WrapAzimuthDeg(725.5), 5.5);
  EXPECT_LT(WrapAzimuthDeg(-1e-17), 360.0);
  EXPECT_TRUE(std::isnan(WrapAzimuthDeg(NAN)));
}

TEST(AngDiffDeg, TakesTheShortWayAcrossNorth) {
  EXPECT_DOUBLE_EQ(AngDiffDeg(1.0, 359.0), 2.0);
  EXPECT_DOUBLE_EQ(AngDiffDeg(359.0, 1.0), -2.0);
  EXPECT_DOUBLE_EQ(AngDiffDeg(90.0, 270.0), -180.0);
}

TEST(DegToRad, RoundTrips) {
  for (double d = -720.0; d <= 720.0; d += 7.3) EXPECT_NEAR(RadToDeg(DegToRad(d)), d, 1e-12);
}

TEST(HrCheck, ThrowsLogicErrorWithMessage) {
  try {
    HR_CHECK(1 + 1 == 3) << "arithmetic";
    FAIL() << "no throw";
  } catch (const LogicError& e) {
    EXPECT_NE(std::string(e.what()).find("arithmetic"), std::string::npos);
  }
}

}  // namespace
}  // namespace horizonreg
