// Tests for analyzers/time_offset.h: the offset between two trajectories of one motion, from the motion.
#include "analyzers/time_offset.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace driftlab::analyzers {
namespace {

/// A hand-held wander: position and heading vary at a few tenths of a hertz, in 3D.
std::pair<Eigen::Vector3d, Eigen::Quaterniond> wander(double s) {
  const Eigen::Vector3d p(std::sin(0.7 * s) + 0.3 * std::sin(2.3 * s), std::cos(0.4 * s) + 0.2 * std::sin(1.7 * s + 1),
                          0.3 * std::sin(0.9 * s));
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5 * std::sin(0.6 * s) + 0.2 * std::sin(1.9 * s), Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.3 * std::sin(1.1 * s), Eigen::Vector3d::UnitX()));
  return {p, q};
}

/// The motion sampled every `period` from `start` for `duration`, with its stamps shifted by `stamp_shift` (a clock
/// that many seconds ahead), in another frame, scaled (a monocular estimate's unknown scale) and noisy.
Trajectory observe(double start, double duration, double period, double stamp_shift, double scale, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Eigen::Quaterniond frame(Eigen::AngleAxisd(1.0, Eigen::Vector3d(1, 2, 3).normalized()));
  Trajectory t;
  for (double s = start; s < start + duration; s += period) {
    const auto [p, q] = wander(s);
    const Eigen::Vector3d jitter = 0.002 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    t.push_back(s + stamp_shift, scale * (frame * p) + Eigen::Vector3d(4, -2, 1) + jitter, frame * q);
  }
  return t;
}

TEST(EstimateTimeOffset, FindsAShiftOfTheClockWhateverTheFrameScaleAndRate) {
  // Ground truth at 100 Hz for 60 s; the estimate at 30 Hz over 40 s of it, stamped by a clock 0.2378 s behind (and,
  // in a second case, on another time base altogether, a million seconds off).
  const Trajectory ref = observe(1000, 60, 0.01, 0, 1, 1);
  for (const double shift : {-0.2378, 1e6 + 0.0123}) {
    SCOPED_TRACE(shift);
    const Trajectory est = observe(1010, 40, 1.0 / 30, shift, 0.37, 2);
    const TimeOffset o = estimate_time_offset(ref, est);
    ASSERT_TRUE(o.found) << o.problem;
    // The offset to add to the estimate's stamps is minus the clock's shift; sampling at 30 Hz and 2 mm noise
    // leave it within a millisecond.
    EXPECT_NEAR(o.offset_s, -shift, 1e-3);
    EXPECT_GT(o.confidence, 0.95);
    EXPECT_EQ(o.signal, "speed and angular speed");
    EXPECT_NEAR(o.overlap_s, 40, 1.0);
  }
}

TEST(EstimateTimeOffset, NeedsMotionOverlapAndStamps) {
  // A constant velocity says nothing about time: nothing correlates.
  Trajectory straight;
  for (int i = 0; i < 1000; ++i) straight.push_back(0.01 * i, Eigen::Vector3d(0.01 * i, 0, 0), Eigen::Quaterniond::Identity());
  const TimeOffset flat = estimate_time_offset(straight, straight);
  EXPECT_FALSE(flat.found && flat.confidence > 0.5) << flat.offset_s << " " << flat.confidence;
  // Too short, or without stamps.
  const Trajectory ref = observe(0, 60, 0.01, 0, 1, 1);
  EXPECT_FALSE(estimate_time_offset(ref, observe(0, 1, 0.01, 0, 1, 2)).found);
  Trajectory unstamped = ref;
  unstamped.stamped = false;
  EXPECT_NE(estimate_time_offset(ref, unstamped).problem.find("without stamps"), std::string::npos);
  // A short estimate (10 s at 20 Hz, within a 60 s reference) is found inside it.
  const TimeOffset part = estimate_time_offset(ref, observe(25, 10, 0.05, 3.0, 1, 3));
  ASSERT_TRUE(part.found) << part.problem;
  EXPECT_NEAR(part.offset_s, -3.0, 2e-3);
  // One stray stamp thirty years on stretches the reference to 1e9 s: the search coarsens within bounded memory
  // and time instead of sampling a billion seconds finely.
  Trajectory stray = ref;
  stray.push_back(stray.stamps.back() + 1e9, stray.positions.back(), stray.orientations.back());
  const TimeOffset far = estimate_time_offset(stray, observe(25, 10, 0.05, 3.0, 1, 3));
  EXPECT_TRUE(!far.found || std::isfinite(far.offset_s));
}

}  // namespace
}  // namespace driftlab::analyzers
