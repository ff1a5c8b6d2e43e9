// DroneEkf and DelayedDroneEkf: alignment from the accelerometer and magnetometer; tracking a known 3D flight (a
// climbing circle with a rocking roll) from noisy, biased IMU samples and GNSS, barometer and magnetometer; the gyro
// bias estimated; a GNSS outlier refused by the innovation test and counted; late GNSS fixes re-applied to the
// in-order result; IMU samples older than the window rejected and counted (the drone_timebase story's mechanism).
#include "estimator/drone_ekf.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "lcmtypes/planar.h"
#include "tests/estimator/drone_flight.h"

namespace driftlab::estimator {
namespace {

using namespace test;  // NOLINT: the flight's constants and generator

DroneEkf started() {
  const Truth truth;
  DroneEkf e(DroneEkfNoise{}, kDeclination, kOriginAlt);
  ImuSample imu;
  imu.accel = truth.attitude(0).inverse() * (truth.acceleration(0) + Eigen::Vector3d(0, 0, kG));
  GnssFix g;
  g.position = truth.position(0);
  e.init(Time::from_us(kT0), imu, MagField{truth.attitude(0).inverse() * field_world()}, g,
         BaroAltitude{kOriginAlt + truth.position(0).z() + kBaroOffset, 0.1});
  return e;
}

double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) { return a.angularDistance(b); }

TEST(DroneEkf, AlignsTiltFromTheAccelerometerAndHeadingFromTheMagnetometer) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d accel = q.inverse() * Eigen::Vector3d(0, 0, kG);
  const Eigen::Vector3d mag = q.inverse() * field_world();
  EXPECT_LT(angle_between(align(accel, mag, kDeclination), q), 1e-9);
  EXPECT_NEAR(wrap_angle(magnetic_heading(mag, q, kDeclination) - heading_of(q)), 0, 1e-9);
  EXPECT_NEAR(heading_of(q), 2.5, 1e-9);
  // Ignoring the declination turns the heading by it.
  EXPECT_NEAR(wrap_angle(magnetic_heading(mag, q, 0) - 2.5), kDeclination, 1e-9);
}

TEST(DroneEkf, TracksAFlightAndEstimatesTheGyroBias) {
  const Truth truth;
  DelayedDroneEkf ekf(started(), 0.3);
  const auto data = flight(1);
  double worst_position = 0, worst_attitude = 0;
  for (const auto& s : data) {
    ASSERT_TRUE(ekf.add(Time::from_us(s.utime), s.m));
    const double t = static_cast<double>(s.utime - kT0) * 1e-6;
    if (t < 10) continue;  // converging: biases and baro offset
    worst_position = std::max(worst_position, (ekf.filter().position() - truth.position(t)).norm());
    worst_attitude = std::max(worst_attitude, angle_between(ekf.filter().attitude(), truth.attitude(t)));
  }
  const DroneEkf& f = ekf.filter();
  // GNSS at 0.3 m (0.5 m vertical) per fix, averaged by the filter with the IMU: well under a fix's own error.
  EXPECT_LT(worst_position, 0.6);
  EXPECT_LT(worst_attitude, 0.03);  // under 2 degrees, all the time
  EXPECT_LT((f.velocity() - truth.velocity(60)).norm(), 0.15);
  EXPECT_LT((f.gyro_bias() - kGyroBias).cwiseAbs().maxCoeff(), 0.003);
  EXPECT_NEAR(f.baro_offset(), kBaroOffset, 0.3);
  EXPECT_LT(angle_between(f.attitude(), truth.attitude(60)), 0.02);
  // Everything fused, nothing refused on clean data (5 sigma gates).
  EXPECT_EQ(f.counts().fused[0], 15000);
  EXPECT_EQ(f.counts().fused[1], 300);
  EXPECT_EQ(f.counts().outliers[1] + f.counts().outliers[2] + f.counts().outliers[3], 0);
  const DroneEkf::Cov& P = f.covariance();
  EXPECT_LT((P - P.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  for (int i = 0; i < DroneEkf::kN; ++i) EXPECT_GT(P(i, i), 0);
}

TEST(DroneEkf, AGnssFixFarOutsideItsAccuracyIsAnOutlier) {
  const Truth truth;
  DelayedDroneEkf ekf(started(), 0.3);
  const auto data = flight(2);
  for (std::size_t i = 0; i < data.size() / 2; ++i) ekf.add(Time::from_us(data[i].utime), data[i].m);
  const DroneEkf before = ekf.filter();
  GnssFix jump;
  const double t = static_cast<double>(before.time().us() - kT0) * 1e-6;
  jump.position = truth.position(t) + Eigen::Vector3d(20, 0, 0);  // a multipath jump of 20 m at eph 0.3 m
  jump.velocity = truth.velocity(t);
  jump.eph = 0.3;
  jump.epv = 0.5;
  jump.speed_accuracy = 0.1;
  ASSERT_TRUE(ekf.add(before.time(), jump));  // in the window: applied, but refused by the innovation test
  EXPECT_EQ(ekf.filter().counts().outliers[1], 1);
  EXPECT_EQ(ekf.filter().position(), before.position());
}

// An estimate that has left the GNSS behind (here: every fix from half-way on 20 m east of where the IMU says,
// as after a divergence) does not stay lost: after reset_s (5 s) of outliers it starts from the fix again, once.
TEST(DroneEkf, FixesThatAreAllOutliersForFiveSecondsResetThePosition) {
  const Truth truth;
  DroneEkf ekf = started();
  const auto data = flight(2);
  int64_t reset_at = 0;
  for (const Stamped& s : data) {
    DroneMeasurement m = s.m;
    const bool shifted = s.utime - kT0 > 30000000;
    if (auto* g = std::get_if<GnssFix>(&m); g != nullptr && shifted) g->position.x() += 20;
    ekf.update(Time::from_us(s.utime), m);
    if (reset_at == 0 && ekf.counts().resets[1] > 0) reset_at = s.utime;
  }
  ASSERT_GT(reset_at, 0);
  // The first shifted fix at 30.2 s; outliers for more than 5 s: the reset with the first fix after 35.2 s.
  EXPECT_NEAR(static_cast<double>(reset_at - kT0) * 1e-6, 35.4, 0.25);
  EXPECT_EQ(ekf.counts().resets[1], 1);
  const double t = static_cast<double>(ekf.time().us() - kT0) * 1e-6;
  EXPECT_LT((ekf.position() - truth.position(t) - Eigen::Vector3d(20, 0, 0)).norm(), 1.0);
}

TEST(DelayedDroneEkf, LateGnssFixesWithinTheWindowGiveTheInOrderResult) {
  const auto in_order = flight(3);
  // Every GNSS fix 120 ms late, as a receiver's latency makes it (30 IMU samples arrive before it).
  std::vector<std::pair<int64_t, Stamped>> arrivals;
  arrivals.reserve(in_order.size());
  for (const auto& s : in_order) arrivals.push_back({s.utime + (std::holds_alternative<GnssFix>(s.m) ? 120000 : 0), s});
  std::stable_sort(arrivals.begin(), arrivals.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  DelayedDroneEkf a(started(), 0.3), b(started(), 0.3);
  for (const auto& s : in_order) a.add(Time::from_us(s.utime), s.m);
  for (const auto& [arrival, s] : arrivals) ASSERT_TRUE(b.add(Time::from_us(s.utime), s.m));
  EXPECT_EQ(b.counters().rejected, 0);
  EXPECT_GE(b.counters().reapplied, 299);  // all but the fixes after the last IMU sample
  EXPECT_LT((a.filter().position() - b.filter().position()).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT(a.filter().attitude().angularDistance(b.filter().attitude()), 1e-9);
  EXPECT_LT((a.filter().covariance() - b.filter().covariance()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(DelayedDroneEkf, ImuSamplesReorderedByJitterGiveTheInOrderResult) {
  // Every IMU sample delayed by exponential jitter of 8 ms mean (twice the sample period: a third arrive after a
  // later one); the others on time.
  const auto in_order = flight(5);
  std::mt19937_64 rng(5);
  std::exponential_distribution<double> jitter(1 / 8000.0);
  std::vector<std::pair<int64_t, Stamped>> arrivals;
  for (const auto& s : in_order) {
    const bool imu = std::holds_alternative<ImuSample>(s.m);
    arrivals.push_back({s.utime + (imu ? static_cast<int64_t>(jitter(rng)) : 0), s});
  }
  std::stable_sort(arrivals.begin(), arrivals.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  DelayedDroneEkf a(started(), 0.3), b(started(), 0.3);
  for (const auto& s : in_order) a.add(Time::from_us(s.utime), s.m);
  for (const auto& [arrival, s] : arrivals) {
    ASSERT_TRUE(b.add(Time::from_us(s.utime), s.m))
        << "stamp " << s.utime - kT0 << " arrival " << arrival - kT0 << " filter " << b.filter().time().us() - kT0
        << " rejected " << b.counters().rejected << " refused " << b.counters().refused;
  }
  EXPECT_EQ(b.counters().rejected, 0);
  EXPECT_GT(b.counters().reapplied, 1000);
  EXPECT_LT((a.filter().position() - b.filter().position()).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT(a.filter().attitude().angularDistance(b.filter().attitude()), 1e-9);
}

TEST(DelayedDroneEkf, ImuSamplesOlderThanTheWindowAreRejectedAndCounted) {
  // The IMU stamped on a clock 0.5 s behind the filter's (fixed by GNSS, baro, mag): with a 0.3 s window every
  // IMU sample after the first correction is older than the window, and none moves the state.
  const auto data = flight(4);
  DelayedDroneEkf ekf(started(), 0.3);
  int64_t imu = 0;
  for (const auto& s : data) {
    const bool is_imu = std::holds_alternative<ImuSample>(s.m);
    imu += is_imu;
    ekf.add(Time::from_us(is_imu ? s.utime - 500000 : s.utime), s.m);
  }
  EXPECT_EQ(imu, 15000);
  // All but those stamped before the first other measurement's time minus the window.
  EXPECT_GT(ekf.counters().rejected, 14900);
  EXPECT_EQ(ekf.counters().rejected + ekf.filter().counts().fused[0], imu);
}

}  // namespace
}  // namespace driftlab::estimator
