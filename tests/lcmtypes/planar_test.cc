// lcmtypes/planar.h: wrap_angle's boundary, (-pi, pi] (-pi becomes pi), whole turns removed exactly enough that
// small angles pass unchanged; yaw_of and yaw_quaternion as inverses.
#include "lcmtypes/planar.h"

#include <gtest/gtest.h>

#include <cmath>

namespace driftlab {
namespace {

TEST(WrapAngle, TheBoundaryIsMinusPiExcludedPiIncluded) {
  EXPECT_EQ(wrap_angle(M_PI), M_PI);
  EXPECT_EQ(wrap_angle(-M_PI), M_PI);
  EXPECT_EQ(wrap_angle(3 * M_PI), M_PI);
  EXPECT_EQ(wrap_angle(-3 * M_PI), M_PI);
  // Just inside the boundary stays inside, on its side.
  const double inside = std::nextafter(-M_PI, 0.0);
  EXPECT_EQ(wrap_angle(inside), inside);
  EXPECT_EQ(wrap_angle(std::nextafter(M_PI, 0.0)), std::nextafter(M_PI, 0.0));
}

TEST(WrapAngle, LeavesAnglesInRangeAsTheyAreAndRemovesWholeTurns) {
  for (double a : {0.0, -0.0, 1e-12, -1e-12, 0.5, -0.5, 3.0, -3.0}) EXPECT_EQ(wrap_angle(a), a) << a;
  EXPECT_EQ(wrap_angle(2 * M_PI), 0.0);
  EXPECT_NEAR(wrap_angle(2 * M_PI + 0.25), 0.25, 1e-15);
  EXPECT_NEAR(wrap_angle(-2 * M_PI - 0.25), -0.25, 1e-15);
  EXPECT_NEAR(wrap_angle(100 * M_PI + 1), 1, 1e-13);
  for (int i = -2000; i <= 2000; ++i) {
    const double a = i * 0.01;
    const double w = wrap_angle(a);
    EXPECT_GT(w, -M_PI) << a;
    EXPECT_LE(w, M_PI) << a;
    const double turns = (a - w) / (2 * M_PI);
    EXPECT_NEAR(turns, std::round(turns), 1e-12) << a;
  }
}

TEST(WrapAngle, AnAngleDifferenceTakesTheShorterWayRound) {
  EXPECT_NEAR(wrap_angle(-3.1 - 3.1), 2 * M_PI - 6.2, 1e-12);  // from 3.1 rad to -3.1 rad: 0.083 rad forward
  EXPECT_NEAR(wrap_angle(3.1 - -3.1), 6.2 - 2 * M_PI, 1e-12);
}

TEST(Planar, YawOfAndYawQuaternionAreInverses) {
  for (double yaw : {0.0, 0.3, -1.2, 2.9, -2.9, M_PI}) {
    const quaternion_t q = yaw_quaternion(yaw);
    EXPECT_NEAR(std::hypot(q.w, q.z), 1, 1e-15);
    EXPECT_NEAR(wrap_angle(yaw_of(q) - yaw), 0, 1e-12) << yaw;
  }
  const Pose2 p;  // the origin, facing +x
  EXPECT_EQ(p.x, 0);
  EXPECT_EQ(p.y, 0);
  EXPECT_EQ(p.yaw, 0);
}

}  // namespace
}  // namespace driftlab
