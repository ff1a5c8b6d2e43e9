// Ekf and DelayedEkf: tracking a known motion from noisy gyro, odometry and poses; gyro bias estimation; late
// measurements re-applied to the same result as in order; too-late ones rejected.
#include "estimator/ekf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace driftlab::estimator {
namespace {

constexpr int64_t kT0 = 1763776800000000;

/// A robot on a circle: v = 0.5 m/s, w = 0.25 rad/s, from the origin facing +x.
struct Truth {
  double v = 0.5, w = 0.25;
  Pose2 at(double t) const {
    const double yaw = w * t;
    return {v / w * std::sin(yaw), v / w * (1 - std::cos(yaw)), wrap_angle(yaw)};
  }
};

struct Stamped {
  int64_t utime;
  Measurement m;
};

/// 20 s of gyro at 200 Hz (bias 0.02 rad/s), odometry twist at 50 Hz and poses at 2 Hz, with noise.
std::vector<Stamped> measurements(uint64_t seed) {
  const Truth truth;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, 1);
  std::vector<Stamped> out;
  for (int i = 1; i <= 4000; ++i) {
    const int64_t t = kT0 + i * 5000;
    out.push_back({t, GyroZ{truth.w + 0.02 + 0.003 * n(rng), 0}});
    if (i % 4 == 0) out.push_back({t, Twist{truth.v + 0.02 * n(rng), truth.w + 0.02 * n(rng), 0, 0}});
    if (i % 100 == 0) {
      Pose2 p = truth.at(static_cast<double>(t - kT0) * 1e-6);
      p.x += 0.05 * n(rng);
      p.y += 0.05 * n(rng);
      p.yaw += 0.02 * n(rng);
      out.push_back({t, PoseFix{p}});
    }
  }
  return out;
}

TEST(Ekf, TracksACircleAndEstimatesTheGyroBias) {
  DelayedEkf ekf(EkfNoise{}, 0.5);
  ekf.init(Time::from_us(kT0), {}, 0.5, 0.25);
  for (const auto& s : measurements(1)) ASSERT_TRUE(ekf.add(Time::from_us(s.utime), s.m));
  const auto& x = ekf.filter().state();
  const Pose2 truth = Truth().at(20.0);
  EXPECT_NEAR(x(Ekf::kX), truth.x, 0.1);
  EXPECT_NEAR(x(Ekf::kY), truth.y, 0.1);
  EXPECT_NEAR(wrap_angle(x(Ekf::kYaw) - truth.yaw), 0, 0.03);
  EXPECT_NEAR(x(Ekf::kV), 0.5, 0.02);
  EXPECT_NEAR(x(Ekf::kW), 0.25, 0.01);
  EXPECT_NEAR(x(Ekf::kBias), 0.02, 0.005);
  EXPECT_EQ(ekf.counters().applied, static_cast<int64_t>(measurements(1).size()));
  // The covariance stays symmetric and positive.
  const Ekf::Cov& P = ekf.filter().covariance();
  EXPECT_LT((P - P.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  for (int i = 0; i < 6; ++i) EXPECT_GT(P(i, i), 0);
}

TEST(DelayedEkf, LateMeasurementsWithinTheWindowGiveTheInOrderResult) {
  const auto in_order = measurements(2);
  // Deliver every odometry twist 30 ms late (after the gyro samples that follow it), as a skewed stream would.
  std::vector<std::pair<int64_t, Stamped>> arrivals;
  for (const auto& s : in_order) {
    const int64_t delay = std::holds_alternative<Twist>(s.m) ? 30000 : 0;
    arrivals.push_back({s.utime + delay, s});
  }
  std::stable_sort(arrivals.begin(), arrivals.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  DelayedEkf a(EkfNoise{}, 0.5), b(EkfNoise{}, 0.5);
  a.init(Time::from_us(kT0), {}, 0.5, 0.25);
  b.init(Time::from_us(kT0), {}, 0.5, 0.25);
  for (const auto& s : in_order) a.add(Time::from_us(s.utime), s.m);
  for (const auto& [arrival, s] : arrivals) ASSERT_TRUE(b.add(Time::from_us(s.utime), s.m));
  EXPECT_EQ(b.counters().reapplied, 999);  // all but the last, which comes after the last gyro sample
  EXPECT_EQ(b.counters().rejected, 0);
  EXPECT_GE(b.counters().replays, 999 * 5);  // each late twist re-applies the 5 gyro samples stamped after it
  // Same measurements, same stamps: the same estimate, to rounding.
  EXPECT_LT((a.filter().state() - b.filter().state()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((a.filter().covariance() - b.filter().covariance()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(DelayedEkf, MeasurementsOlderThanTheWindowAreRejectedAndCounted) {
  DelayedEkf ekf(EkfNoise{}, 0.1);
  ekf.init(Time::from_us(kT0), {}, 0, 0);
  for (int i = 1; i <= 100; ++i) ASSERT_TRUE(ekf.add(Time::from_us(kT0 + int64_t{i} * 5000), GyroZ{0, 0}));
  const Ekf before = ekf.filter();
  EXPECT_FALSE(ekf.add(Time::from_us(kT0 + 500000 - 150000), Twist{1, 1, 0, 0}));  // 150 ms old, window 100 ms
  EXPECT_EQ(ekf.counters().rejected, 1);
  EXPECT_EQ(ekf.filter().state(), before.state());
  EXPECT_TRUE(ekf.add(Time::from_us(kT0 + 500000 - 50000), Twist{0, 0, 0, 0}));  // 50 ms old: re-applied
  EXPECT_EQ(ekf.counters().reapplied, 1);
  // A zero window is the "reject every late measurement" policy.
  DelayedEkf strict(EkfNoise{}, 0);
  strict.init(Time::from_us(kT0), {}, 0, 0);
  ASSERT_TRUE(strict.add(Time::from_us(kT0 + 10000), GyroZ{0, 0}));
  EXPECT_FALSE(strict.add(Time::from_us(kT0 + 5000), GyroZ{0, 0}));
}

TEST(Ekf, NeverLetsANonFiniteNumberIntoItsState) {
  // NaN in 5% of the odometry twists used to make nearly every later estimate NaN, for the rest of the run.
  DelayedEkf ekf(EkfNoise{}, 0.5);
  ASSERT_TRUE(ekf.init(Time::from_us(kT0), {}, 0.5, 0.25));
  int refused = 0, n = 0;
  for (auto s : measurements(4)) {
    if (auto* t = std::get_if<Twist>(&s.m); t != nullptr && ++n % 20 == 0) {
      t->v = NAN;
      ++refused;
    }
    ekf.add(Time::from_us(s.utime), s.m);
    ASSERT_TRUE(ekf.filter().state().allFinite()) << s.utime;
    ASSERT_TRUE(ekf.filter().covariance().allFinite()) << s.utime;
  }
  EXPECT_EQ(ekf.counters().refused, refused);
  EXPECT_NEAR(ekf.filter().state()(Ekf::kV), 0.5, 0.02);  // the good ones still tracked
  const auto x = ekf.filter().state();
  // Finite values no robot measures, which would overflow it on the next step (a speed of 1e300 m/s gives a
  // covariance term of 1e600), and an infinite variance (its gain would be 0 * inf).
  for (const Measurement& m :
       {Measurement(Twist{1e300, 0, 0, 0}), Measurement(PoseFix{{1e308, -1e308, 0}}), Measurement(GyroZ{2e9, 0}),
        Measurement(GyroZ{0.1, INFINITY}), Measurement(Twist{0.5, 0.25, 0, -INFINITY})}) {
    EXPECT_FALSE(ekf.add(Time::from_us(kT0 + 20'000'000), m));
  }
  EXPECT_EQ(ekf.filter().state(), x);
  EXPECT_EQ(ekf.counters().refused, refused + 5);
  // A late measurement that would poison it is refused too, and the filter stays as it was.
  EXPECT_FALSE(ekf.add(Time::from_us(kT0 + 19'900'000), PoseFix{{NAN, 0, 0}}));
  EXPECT_FALSE(ekf.add(Time::from_us(kT0 + 19'900'000), Twist{1e300, 0, 0, 0}));
  EXPECT_EQ(ekf.filter().state(), x);
  // Stamps at the ends of int64_t: no overflow (UBSan), old ones rejected.
  EXPECT_FALSE(ekf.add(Time::from_us(std::numeric_limits<int64_t>::min()), Twist{0.5, 0.25, 0, 0}));
  EXPECT_EQ(ekf.counters().rejected, 1);
}

TEST(Ekf, StartsOnlyFromFiniteValues) {
  Ekf ekf;
  EXPECT_FALSE(ekf.init(Time::from_us(kT0), {{NAN, 0, 0}}, 0, 0));
  EXPECT_FALSE(ekf.init(Time::from_us(kT0), {}, INFINITY, 0));
  EXPECT_FALSE(ekf.initialized());
  EXPECT_TRUE(ekf.init(Time::from_us(kT0), {}, 0, 0));
}

}  // namespace
}  // namespace driftlab::estimator
