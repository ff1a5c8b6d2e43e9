// A scanner's no-return code found in its readings (slam/internal/no_return.h). MIT Killian's CARMEN log, as the
// ROS bag INESC TEC's clf2bag made of it, says range_max 80 m while its SICK answers 51.05-51.12 m (mostly 51.06) for
// a beam without an echo: 1.3% of the readings. As points they sat 51 m ahead of the robot wherever it went, and in
// MIT's long corridors the front end followed them (relation error 3.8 m; 0.055 m without them, SlamOnMoreLogs).
// What must not be taken for a code: the farthest echoes a robot sees, even when it stands still looking at them.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "slam/internal/mrpt_scan.h"
#include "slam/internal/no_return.h"

namespace driftlab::slam::internal {
namespace {

constexpr int kBeams = 180;

/// Walls 1-6 m away on every beam (a corridor's sides and a room), as the scans the code hides among.
std::vector<float> walls(std::mt19937& rng, int beams = kBeams) {
  std::uniform_real_distribution<float> range(1.0f, 6.0f);
  std::vector<float> r(static_cast<size_t>(beams));
  for (auto& x : r) x = range(rng);
  return r;
}

TEST(NoReturnCode, APileAtTheTopOfTheReadingsIsFound) {
  std::mt19937 rng(1);
  NoReturnCode code;
  std::uniform_int_distribution<int> ahead(60, 120);
  int scans = 0;
  for (; scans < 1000 && !code.from(); ++scans) {
    auto r = walls(rng);
    // Down the corridor, a few beams with no echo; Killian's values (51.06 m in 80% of them), and once its stray
    // 51.22.
    for (int k = 0; k < 3; ++k) r[static_cast<size_t>(ahead(rng))] = k < 2 ? 51.06f : 51.11f;
    if (scans == 5) r[90] = 51.22f;
    code.observe(r, 0.1f, 80.0f);
  }
  ASSERT_TRUE(code.from());
  // Three no-echo beams a scan: found once the pile holds 100 readings from 20 beams, some 34 scans in.
  EXPECT_LT(scans, 60);
  EXPECT_GE(code.pile(), NoReturnCode::kMinPile);
  EXPECT_GT(*code.from(), 50.0f);
  EXPECT_LE(*code.from(), 51.05f);
  // The module passes it to the conversion: the code is no point, a far echo short of it is.
  driftlab::laser_scan_t s{};
  s.nranges = 3;
  s.ranges = {51.06f, 49.0f, 51.22f};
  s.angle_min = -0.1f, s.angle_increment = 0.1f, s.angle_max = 0.1f, s.range_min = 0.1f, s.range_max = 80.0f;
  const auto obs = to_mrpt(s, mrpt::poses::CPose2D(), *code.from());
  EXPECT_FALSE(obs->getScanRangeValidity(0));
  EXPECT_TRUE(obs->getScanRangeValidity(1));
  EXPECT_FALSE(obs->getScanRangeValidity(2));
}

TEST(NoReturnCode, ADoorwayAStandingRobotSeesIsNoCode) {
  // Intel's and MIT CSAIL's logs begin so: the robot stands, and through a door two beams read the farthest wall,
  // 17 m, to the centimetre, scan after scan (a pile of hundreds at one value). Few beams: an echo.
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.0f, 0.005f);
  NoReturnCode code;
  for (int scan = 0; scan < 2000; ++scan) {
    auto r = walls(rng);
    r[40] = 17.03f + noise(rng), r[41] = 17.05f + noise(rng);
    code.observe(r, 0.1f, 80.0f);
  }
  EXPECT_FALSE(code.from());
}

TEST(NoReturnCode, AFarWallFacedSquarelyIsNoCode) {
  // A robot standing before a wall 30 m ahead, square to a scanner with beams 0.25 degrees apart, the farthest
  // thing in view, 10 degrees wide: 40 beams, all within 0.4% of the nearest, scan after scan. Many beams and a pile
  // with nothing near it, but readings spread over 30-30.11 m (30 m / cos, and 1 cm of noise): an echo. (It is the
  // one-value test that tells them apart: without it this would be a code.)
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  NoReturnCode code;
  for (int scan = 0; scan < 2000; ++scan) {
    auto r = walls(rng, 720);
    for (int b = 360 - 20; b < 360 + 20; ++b) {
      const float a = static_cast<float>(b - 360) * 0.25f * static_cast<float>(M_PI) / 180.0f;
      r[static_cast<size_t>(b)] = std::round((30.0f / std::cos(a) + noise(rng)) * 100) / 100;  // centimetres
    }
    code.observe(r, 0.1f, 80.0f);
  }
  EXPECT_FALSE(code.from());
}

TEST(NoReturnCode, AThinTailOfFarEchoesIsNoCode) {
  std::mt19937 rng(4);
  std::exponential_distribution<float> far(0.2f);
  NoReturnCode code;
  for (int scan = 0; scan < 3000; ++scan) {
    auto r = walls(rng);
    for (int b = 0; b < kBeams; b += 4) r[static_cast<size_t>(b)] = 1.0f + far(rng);
    code.observe(r, 0.1f, 80.0f);
  }
  EXPECT_FALSE(code.from());
}

TEST(NoReturnCode, ReadingsAtRangeMaxAreLeftToTheConversion) {
  // ACES says range_max 50 m and answers 50.00 m for no echo: mrpt_scan.h already drops those; they are not counted
  // here, and no second code is found below them.
  std::mt19937 rng(5);
  NoReturnCode code;
  for (int scan = 0; scan < 1000; ++scan) {
    auto r = walls(rng);
    for (int b = 70; b < 110; ++b) r[static_cast<size_t>(b)] = 50.0f;
    code.observe(r, 0.1f, 50.0f);
  }
  EXPECT_FALSE(code.from());
}

}  // namespace
}  // namespace driftlab::slam::internal
