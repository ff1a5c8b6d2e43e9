// Tests for analyzers/imu_clock_alignment.h: a flight controller's IMU and a companion computer's copy of it, on two
// clocks, put on one.
#include "analyzers/imu_clock_alignment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace driftlab::analyzers {
namespace {

/// A multirotor's body rates [rad/s] at time s since boot: manoeuvres a few seconds long whose strength wanders, on
/// top of a hover's small corrections.
Eigen::Vector3d body_rates(double s) {
  const double gust = 0.5 + 0.5 * std::sin(0.05 * s) * std::sin(0.31 * s + 1);
  return {gust * (0.6 * std::sin(1.3 * s) + 0.2 * std::sin(4.1 * s)), gust * 0.5 * std::sin(0.9 * s + 2),
          0.3 * std::sin(0.17 * s) * std::sin(2.3 * s) + 0.05 * std::sin(7.0 * s)};
}

/// The rates sampled every period over [from, to) of boot time, stamped by clock(boot time), with Gaussian noise;
/// frame_flu: in MAVROS's forward-left-up frame (y and z negated) rather than PX4's forward-right-down.
template <typename Clock>
AngularRates sample(double from, double to, double period, double noise, bool frame_flu, uint64_t seed, Clock clock) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, noise);
  AngularRates r;
  for (double s = from; s < to; s += period) {
    Eigen::Vector3d w = body_rates(s) + Eigen::Vector3d(n(rng), n(rng), n(rng));
    if (frame_flu) w = Eigen::Vector3d(w.x(), -w.y(), -w.z());
    r.stamps.push_back(clock(s));
    r.rates.push_back(w);
  }
  return r;
}

TEST(AlignImuClocks, PutsBootTimeOnTheWallClockWithItsDrift) {
  // PX4's IMU at 250 Hz for 600 s of boot time; MAVROS's at 50 Hz from 20 s to 580 s, on a wall clock 1.7e9 s later
  // plus 0.4321 s, running 40 ppm fast (a companion computer without NTP: tens of ppm are usual).
  constexpr double kEpoch = 1.7e9 + 0.4321, kDrift = 40e-6;
  const auto wall = [](double boot) { return kEpoch + boot * (1 + kDrift); };
  const AngularRates px4 = sample(0, 600, 0.004, 0.003, false, 1, [](double s) { return s; });
  const AngularRates mavros = sample(20, 580, 0.02, 0.01, true, 2, wall);
  const ClockAlignment a = align_imu_clocks(mavros, px4);
  ASSERT_TRUE(a.found) << a.problem;
  EXPECT_GT(a.confidence, 0.95);
  EXPECT_NEAR(a.overlap_s, 560, 5);
  ASSERT_TRUE(a.drift_measured);
  EXPECT_TRUE(a.drift_applied);
  // Each segment's offset is good to about a millisecond over 70 s: the slope to a few ppm.
  EXPECT_NEAR(a.drift, kDrift, 5e-6) << a.drift_ci95;
  // Over the whole overlap the mapping is within 2 ms of the truth (a tenth of MAVROS's 20 ms IMU period).
  for (const double boot : {20.0, 300.0, 580.0}) EXPECT_NEAR(a.to_reference(boot), wall(boot), 2e-3) << boot;
}

TEST(AlignImuClocks, NoDriftAppliedWhereThereIsNone) {
  const auto wall = [](double boot) { return 1.7e9 + 12.5 + boot; };
  const AngularRates px4 = sample(0, 300, 0.004, 0.003, false, 3, [](double s) { return s; });
  const AngularRates mavros = sample(10, 290, 0.02, 0.01, true, 4, wall);
  const ClockAlignment a = align_imu_clocks(mavros, px4);
  ASSERT_TRUE(a.found) << a.problem;
  ASSERT_TRUE(a.drift_measured);
  // The measured slope is within its own interval of zero: nothing to apply. And small: a segment's offset is
  // good to about a millisecond, which over the 280 s overlap is a slope of a few ppm (3 ppm with GCC's build, 5
  // with clang's, from the same samples); 10 ppm is a tenth of the 100 ppm the diagnosis calls a drifting clock.
  EXPECT_FALSE(a.drift_applied) << a.drift_measured_value << " +/- " << a.drift_ci95;
  EXPECT_LT(std::abs(a.drift_measured_value), 10e-6);
  EXPECT_NEAR(a.to_reference(150), wall(150), 2e-3);
}

TEST(AlignImuClocks, ShortFlightsGetNoDriftAndUnrelatedImusNoAlignment) {
  const auto wall = [](double boot) { return 1.7e9 + boot - 3.25; };
  const AngularRates px4 = sample(0, 60, 0.004, 0.003, false, 5, [](double s) { return s; });
  const AngularRates mavros = sample(5, 55, 0.02, 0.01, true, 6, wall);
  const ClockAlignment a = align_imu_clocks(mavros, px4);
  ASSERT_TRUE(a.found) << a.problem;
  EXPECT_FALSE(a.drift_measured);  // 50 s of overlap: under the 120 s a drift is measured on
  EXPECT_NEAR(a.offset_s, 1.7e9 - 3.25, 2e-3);

  // Another vehicle's IMU (the same kind of motion, 37 s later in its flight): no common timing.
  const AngularRates other = sample(42, 92, 0.02, 0.01, true, 7, [](double s) { return s; });
  AngularRates shuffled = other;
  std::mt19937_64 rng(8);
  std::shuffle(shuffled.rates.begin(), shuffled.rates.end(), rng);
  const ClockAlignment none = align_imu_clocks(shuffled, px4);
  EXPECT_FALSE(none.found) << none.offset_s << " " << none.confidence;
  EXPECT_NE(none.problem, "");

  // Too little data.
  AngularRates few;
  few.stamps = {0, 1, 2};
  few.rates.assign(3, Eigen::Vector3d(0.1, 0, 0));
  EXPECT_FALSE(align_imu_clocks(few, px4).found);
}

}  // namespace
}  // namespace driftlab::analyzers
