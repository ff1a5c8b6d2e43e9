// Our scans as MRPT observations (slam/internal/mrpt_scan.h): which readings are points. A SICK reports a "no return"
// code at or just below its maximum range (50 m, 81.83 m), and the bags made from CARMEN logs carry range_max at or
// a little above it (Freiburg's clinic log: range_max 81.9, with 81.83 and 81.91 as its no-echo readings; 5,849 of
// its readings at 81.83 drew a phantom circle the front end matched against).
#include <gtest/gtest.h>

#include <cmath>

#include "slam/internal/mrpt_scan.h"

namespace driftlab::slam::internal {
namespace {

driftlab::laser_scan_t scan_of(std::vector<float> ranges, float range_max) {
  driftlab::laser_scan_t s{};
  s.nranges = static_cast<int>(ranges.size());
  s.ranges = std::move(ranges);
  s.angle_min = -1.5708f;
  s.angle_increment = 3.1416f / static_cast<float>(s.nranges - 1);
  s.angle_max = s.angle_min + s.angle_increment * static_cast<float>(s.nranges - 1);
  s.range_min = 0.1f;
  s.range_max = range_max;
  return s;
}

TEST(MrptScan, ReadingsAtTheNoReturnCodeAreNotPoints) {
  // The clinic log's own values: its two no-echo codes, a far wall at 51 m, a near one, and too close.
  const auto obs = to_mrpt(scan_of({81.83f, 81.91f, 51.22f, 3.5f, 0.05f, NAN}, 81.9f), mrpt::poses::CPose2D());
  EXPECT_FALSE(obs->getScanRangeValidity(0));  // 0.08% below range_max: the code, not an echo
  EXPECT_FALSE(obs->getScanRangeValidity(1));  // above range_max
  EXPECT_TRUE(obs->getScanRangeValidity(2));
  EXPECT_TRUE(obs->getScanRangeValidity(3));
  EXPECT_FALSE(obs->getScanRangeValidity(4));  // below range_min
  EXPECT_FALSE(obs->getScanRangeValidity(5));
}

TEST(MrptScan, AnEchoJustOutsideTheOnePercentBandIsAPoint) {
  // The band is 1% of range_max: 0.5 m on a 50 m scanner (ACES's code is exactly 50 m), 0.3 m on the simulator's
  // 30 m one. A reading 2% short of the maximum is a wall.
  const auto obs = to_mrpt(scan_of({49.0f, 49.6f, 50.0f}, 50.0f), mrpt::poses::CPose2D());
  EXPECT_TRUE(obs->getScanRangeValidity(0));
  EXPECT_FALSE(obs->getScanRangeValidity(1));
  EXPECT_FALSE(obs->getScanRangeValidity(2));
}

}  // namespace
}  // namespace driftlab::slam::internal
