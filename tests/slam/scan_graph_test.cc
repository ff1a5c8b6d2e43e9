// The 2D scan graph's front end with the odometry weighed in (slam/internal/scan_graph.h, match_odometry): a scan
// match and the odometry's prediction combined by their information. Along a corridor, where the match pins
// nothing down, the odometry's position stands; across it and in heading, the match's. And what of the current
// points an old place's scans could have seen, for its loop tests (loop_seen_only).
#include <gtest/gtest.h>
#include <mrpt/obs/CObservation2DRangeScan.h>

#include <Eigen/Geometry>

#include <cmath>
#include <utility>
#include <vector>

#include "slam/internal/scan_graph.h"

namespace driftlab::slam::internal {
namespace {

using mrpt::poses::CPose2D;

/// The information of a match in a corridor along `axis` (rad): 10,000 across it and in heading (a point-to-line
/// match of 100 wall points with 1 cm of noise), `along` along it.
Eigen::Matrix3d corridor(double axis, double along) {
  const Eigen::Rotation2Dd r(axis);
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  info.topLeftCorner<2, 2>() =
      r.toRotationMatrix() * Eigen::Vector2d(along, 1e4).asDiagonal() * r.toRotationMatrix().transpose();
  info(2, 2) = 1e4;
  return info;
}

TEST(Combine, AlongACorridorTheOdometryStandsAcrossItTheMatch) {
  // The match slid 0.5 m along a corridor running at 30 degrees; across it, it is 5 cm from the prediction.
  const double axis = M_PI / 6;
  const Eigen::Vector2d along(std::cos(axis), std::sin(axis)), across(-std::sin(axis), std::cos(axis));
  const Eigen::Vector2d matched_xy(2, 1), predicted_xy = matched_xy - 0.5 * along + 0.05 * across;
  const CPose2D matched(matched_xy.x(), matched_xy.y(), 0.3), predicted(predicted_xy.x(), predicted_xy.y(), 0.31);
  const Eigen::Matrix3d odometry = odometry_information(CPose2D(0.3, 0, 0.01), {0.05, 0.01, 0.05, 0.005});
  // 2.5 cm and 0.55 degrees over a 0.3 m step with a 0.01 rad turn: 1,600 and 33,058 of information.
  EXPECT_NEAR(odometry(0, 0), 1 / (0.025 * 0.025), 1e-6);
  EXPECT_NEAR(odometry(1, 1), odometry(0, 0), 1e-9);
  EXPECT_NEAR(odometry(2, 2), 1 / (0.0055 * 0.0055), 1e-6);
  const CPose2D both = combine(matched, corridor(axis, 1.0), predicted, odometry);
  const Eigen::Vector2d moved = Eigen::Vector2d(both.x(), both.y()) - matched_xy;
  // Along: the odometry's (1,600 against 1): 0.5 m * 1600 / 1601 of the way to the prediction.
  EXPECT_NEAR(moved.dot(along), -0.5 * 1600 / 1601, 1e-9);
  // Across: the match's (10,000 against 1,600).
  EXPECT_NEAR(moved.dot(across), 0.05 * 1600 / 11600, 1e-9);
  // Heading: 33,058 against 10,000.
  EXPECT_NEAR(both.phi(), 0.3 + 0.01 * odometry(2, 2) / (odometry(2, 2) + 1e4), 1e-9);

  // Where the match pins the position down in every direction (a room), the odometry moves it by 14% of the way.
  const Eigen::Matrix3d room = corridor(axis, 1e4);
  const CPose2D in_room = combine(matched, room, predicted, odometry);
  EXPECT_NEAR((Eigen::Vector2d(in_room.x(), in_room.y()) - matched_xy).dot(along), -0.5 * 1600 / 11600, 1e-9);
}

TEST(Combine, HeadingsEitherSideOfPiMeetNearPi) {
  const Eigen::Matrix3d equal = Eigen::Matrix3d::Identity();
  const CPose2D both = combine(CPose2D(0, 0, M_PI - 0.02), equal, CPose2D(0, 0, -M_PI + 0.02), equal);
  EXPECT_NEAR(std::abs(both.phi()), M_PI, 1e-9);  // not 0, the mean of the two numbers
}

/// A SICK-like scan: 181 beams over 180 degrees, every one hitting at `range` (or none where `range` is 0), its
/// sensor 0.2 m ahead of the base.
mrpt::obs::CObservation2DRangeScan scan_at(float range, bool right_to_left = true) {
  mrpt::obs::CObservation2DRangeScan scan;
  scan.aperture = static_cast<float>(M_PI);
  scan.rightToLeft = right_to_left;
  scan.maxRange = 80;
  scan.sensorPose = mrpt::poses::CPose3D(0.2, 0, 0, 0, 0, 0);
  scan.resizeScan(181);
  for (size_t i = 0; i < 181; ++i) {
    scan.setScanRange(i, range);
    scan.setScanRangeValidity(i, range > 0);
  }
  return scan;
}

// loop_seen_only: of the current points, a loop test's ICP takes those an old scan could have seen. An old scan at
// (10, 0) facing along -x (the way back along a corridor) whose beams hit at 4 m: it saw the 4 m in front of its
// sensor, out to 10 - 0.2 - 4 = 5.8 m on the x axis, and nothing behind it.
TEST(SeenPoints, OnlyWhatAnOldScanCouldHaveSeen) {
  const auto old = scan_at(4);
  const std::vector<std::pair<const mrpt::obs::CObservation2DRangeScan*, CPose2D>> scans = {
      {&old, CPose2D(10, 0, M_PI)}};
  mrpt::maps::CSimplePointsMap query;  // in the frame of the current pose, (1, 0) facing +x
  query.insertPoint(6, 0, 0);          // at (7, 0): 2.8 m in front of the old sensor, within its 4 m
  query.insertPoint(4.7, 0, 0);        // at (5.7, 0): 4.1 m, beyond the hit but within the 0.3 m margin
  query.insertPoint(4.3, 0, 0);        // at (5.3, 0): 4.5 m, behind what the beam hit
  query.insertPoint(10, 0, 0);         // at (11, 0): behind the old sensor, outside its aperture
  query.insertPoint(8.5, 3.5, 0);      // at (9.5, 3.5): 3.5 m off, 5 degrees inside the old aperture's right edge
  const auto seen = seen_points(scans, query, CPose2D(1, 0, 0), 0.3);
  ASSERT_EQ(seen.size(), 3u);
  float x = 0, y = 0;
  seen.getPoint(0, x, y);
  EXPECT_FLOAT_EQ(x, 6);
  seen.getPoint(1, x, y);
  EXPECT_FLOAT_EQ(x, 4.7f);
  seen.getPoint(2, x, y);
  EXPECT_FLOAT_EQ(x, 8.5f);
  EXPECT_FLOAT_EQ(y, 3.5f);

  // Beams clockwise instead: the same field of view, the same points.
  const auto clockwise = scan_at(4, false);
  EXPECT_EQ(seen_points({{&clockwise, CPose2D(10, 0, M_PI)}}, query, CPose2D(1, 0, 0), 0.3).size(), 3u);
  // Beams without a return see as far as the scanner's range: every point in front of the sensor.
  const auto no_return = scan_at(0);
  EXPECT_EQ(seen_points({{&no_return, CPose2D(10, 0, M_PI)}}, query, CPose2D(1, 0, 0), 0.3).size(), 4u);
  // Two old scans: what either saw (the second at the origin facing +x saw (11, 0), 10.8 m from its sensor).
  const auto long_range = scan_at(20);
  EXPECT_EQ(seen_points({{&old, CPose2D(10, 0, M_PI)}, {&long_range, CPose2D()}}, query, CPose2D(1, 0, 0), 0.3).size(),
            5u);
  EXPECT_EQ(seen_points({}, query, CPose2D(1, 0, 0), 0.3).size(), 0u);
}

TEST(OdometryInformation, GrowsLooserWithTravelAndTurnAndNeverInfinite) {
  const std::array<double, 4> noise = {0.05, 0.01, 0.05, 0.005};
  const auto still = odometry_information(CPose2D(), noise), far = odometry_information(CPose2D(2, 0, 0), noise);
  EXPECT_NEAR(still(0, 0), 1e4, 1e-6);  // the floor: 1 cm
  EXPECT_NEAR(far(0, 0), 1 / (0.11 * 0.11), 1e-6);
  const auto turned = odometry_information(CPose2D(0, 0, -1), noise);
  EXPECT_NEAR(turned(2, 2), 1 / (0.055 * 0.055), 1e-6);
  const auto exact = odometry_information(CPose2D(), {0, 0, 0, 0});  // a noise of zero: exact, still finite
  EXPECT_TRUE(exact.allFinite());
  EXPECT_GT(exact(0, 0), 1e11);
}

}  // namespace
}  // namespace driftlab::slam::internal
