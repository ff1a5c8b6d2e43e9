// The drone estimator as a module on the replay host: fed the known flight's sensors as LCM messages (GNSS as
// latitude and longitude, the barometer as pressure), it publishes estimates that follow the truth and a status
// with nothing rejected; with the IMU stamped on another clock its samples are rejected by reason (stale when
// 2 s behind, late when 0.4 s behind and past the filter's window, from the future when 1 s ahead) and the status
// and the module's warnings say so.
#include "estimator/drone_estimator_module.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <variant>

#include "core/geo.h"
#include "driftlab/barometer_t.hpp"
#include "driftlab/estimator_status_t.hpp"
#include "driftlab/gnss_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/magnetometer_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "tests/estimator/drone_flight.h"
#include "tests/fakes/fake_bus.h"

namespace driftlab::estimator {
namespace {

using namespace test;  // NOLINT: the flight's constants and generator

const geo::LocalFrame kWorld({47.397742, 8.545594, kOriginAlt});

driftlab::header_t header(int64_t utime) {
  driftlab::header_t h{};
  h.utime = utime;
  h.frame_id = "base_link";
  return h;
}

/// Plays the flight's measurements at their true times, the IMU's header stamped `imu_shift_us` off and, with
/// `imu_jitter_us`, each IMU sample arriving after an exponential delay of that mean (so some overtake others).
Status play(driftlab::test::FakeBus& bus, int64_t imu_shift_us, Eigen::Vector3d* first_fix = nullptr,
            double imu_jitter_us = 0) {
  struct Arrival {
    int64_t utime;
    std::string channel;
    std::vector<uint8_t> bytes;
  };
  std::vector<Arrival> arrivals;
  std::mt19937_64 rng(11);
  std::exponential_distribution<double> jitter(imu_jitter_us > 0 ? 1 / imu_jitter_us : 1.0);
  auto send = [&arrivals](const std::string& channel, const auto& m, Time t) -> Status {
    arrivals.push_back({t.us(), channel, driftlab::test::encode(m)});
    return {};
  };
  bool have_fix = false;
  for (const Stamped& s : flight(7)) {
    Status st;
    if (const auto* imu = std::get_if<ImuSample>(&s.m)) {
      driftlab::imu_t m{};
      m.header = header(s.utime + imu_shift_us);
      m.orientation = {1, 0, 0, 0};
      m.orientation_covariance[0] = -1;
      m.angular_velocity = {imu->gyro.x(), imu->gyro.y(), imu->gyro.z()};
      m.linear_acceleration = {imu->accel.x(), imu->accel.y(), imu->accel.z()};
      const int64_t delay = imu_jitter_us > 0 ? static_cast<int64_t>(jitter(rng)) : 0;
      st = send("IMU", m, Time::from_us(s.utime + delay));
    } else if (const auto* g = std::get_if<GnssFix>(&s.m)) {
      if (!have_fix && first_fix) *first_fix = g->position;
      have_fix = true;
      const geo::LatLonAlt p = kWorld.to_global({g->position.x(), g->position.y(), g->position.z()});
      driftlab::gnss_t m{};
      m.header = header(s.utime);
      m.fix_type = 3;
      m.satellites = 12;
      m.latitude_deg = p.latitude_deg;
      m.longitude_deg = p.longitude_deg;
      m.altitude_m = p.altitude_m;
      m.eph_m = g->eph;
      m.epv_m = g->epv;
      m.velocity = {g->velocity.x(), g->velocity.y(), g->velocity.z()};
      m.speed_accuracy_m_s = g->speed_accuracy;
      st = send("GNSS", m, Time::from_us(s.utime));
    } else if (const auto* b = std::get_if<BaroAltitude>(&s.m)) {
      driftlab::barometer_t m{};
      m.header = header(s.utime);
      m.pressure_pa = geo::pressure_at(b->altitude);
      m.temperature_c = 15;
      const double pa_per_m = geo::pressure_at(b->altitude - 0.5) - geo::pressure_at(b->altitude + 0.5);
      m.pressure_variance = std::pow(b->std * pa_per_m, 2);
      st = send("BARO", m, Time::from_us(s.utime));
    } else if (const auto* mag = std::get_if<MagField>(&s.m)) {
      driftlab::magnetometer_t m{};
      m.header = header(s.utime);
      m.magnetic_field = {mag->field.x(), mag->field.y(), mag->field.z()};
      st = send("MAG", m, Time::from_us(s.utime));
    }
    if (!st) return st;
  }
  std::stable_sort(arrivals.begin(), arrivals.end(),
                   [](const Arrival& a, const Arrival& b) { return a.utime < b.utime; });
  for (const Arrival& a : arrivals) {
    if (Status st = bus.deliver(a.channel, a.bytes, Time::from_us(a.utime)); !st) return st;
  }
  return {};
}

DroneEstimatorConfig config() {
  DroneEstimatorConfig c;
  c.declination = kDeclination;
  c.output_channel = "ODOM_OUT";
  c.status_channel = "STATUS_OUT";
  return c;
}

driftlab::estimator_status_t last_status(const driftlab::test::FakeBus& bus) {
  const auto events = bus.published("STATUS_OUT");
  driftlab::estimator_status_t s{};
  if (!events.empty()) s.decode(events.back().data.data(), 0, static_cast<int>(events.back().data.size()));
  return s;
}

/// The largest distance of the published estimates from the truth after the first 10 s (the module's local frame
/// starts at the first fix `origin`; the truth's at kWorld's origin), and how many estimates there were.
double worst_error(const driftlab::test::FakeBus& bus, const Eigen::Vector3d& origin, int* count = nullptr) {
  const Truth truth;
  double worst = 0;
  int n = 0;
  for (const auto& e : bus.published("ODOM_OUT")) {
    driftlab::odometry_t o;
    EXPECT_GT(o.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    const double t = static_cast<double>(o.header.utime - kT0) * 1e-6;
    ++n;
    if (t < 10) continue;
    worst = std::max(worst,
                     (Eigen::Vector3d(o.position.x, o.position.y, o.position.z) + origin - truth.position(t)).norm());
  }
  if (count != nullptr) *count = n;
  return worst;
}

TEST(DroneEstimatorModule, FollowsTheFlightAndRejectsNothing) {
  DroneEstimatorModule est(config());
  driftlab::test::FakeBus bus;
  bus.add(est);
  ASSERT_TRUE(bus.start());
  Eigen::Vector3d origin;
  ASSERT_TRUE(play(bus, 0, &origin));
  ASSERT_TRUE(bus.finish());
  int n = 0;
  EXPECT_LT(worst_error(bus, origin, &n), 0.6);
  EXPECT_GT(n, 14850);  // one estimate per IMU sample after the 0.5 s the start averages
  const auto s = last_status(bus);
  ASSERT_EQ(s.ninputs, 4);
  EXPECT_EQ(s.input[0], "imu");
  EXPECT_GT(s.fused[0], 14850);
  EXPECT_EQ(s.fused[1], 298);  // every fix after the one the filter started from (at 0.4 s)
  for (int i = 0; i < 4; ++i) EXPECT_EQ(s.stale[i] + s.future[i] + s.late[i] + s.outliers[i], 0) << s.input[i];
  EXPECT_TRUE(s.position_valid);
  EXPECT_TRUE(s.attitude_valid);
  EXPECT_TRUE(est.counters().warnings.empty());
}

// IMU samples delayed by transport jitter (8 ms mean, twice their period: a third overtake another) are re-applied
// in stamp order: the estimate follows the flight as when they arrive in order.
TEST(DroneEstimatorModule, FollowsTheFlightWhenJitterReordersTheImu) {
  DroneEstimatorModule est(config());
  driftlab::test::FakeBus bus;
  bus.add(est);
  ASSERT_TRUE(bus.start());
  Eigen::Vector3d origin;
  ASSERT_TRUE(play(bus, 0, &origin, 8000));
  ASSERT_TRUE(bus.finish());
  EXPECT_LT(worst_error(bus, origin), 0.6);
  EXPECT_LT(est.input(DroneEstimatorModule::kImu).late, 10);
}

TEST(DroneEstimatorModule, AnImuOnAnotherClockIsRejectedAndTheReasonCounted) {
  struct Case {
    int64_t shift_us;
    int64_t InputCounts::*reason;
    const char* name;
  };
  for (const Case& c : {Case{-2000000, &InputCounts::stale, "stale"}, Case{-400000, &InputCounts::late, "late"},
                        Case{1000000, &InputCounts::future, "future"}}) {
    SCOPED_TRACE(c.name);
    DroneEstimatorModule est(config());
    driftlab::test::FakeBus bus;
    bus.add(est);
    ASSERT_TRUE(bus.start());
    ASSERT_TRUE(play(bus, c.shift_us));
    ASSERT_TRUE(bus.finish());
    const InputCounts& imu = est.input(DroneEstimatorModule::kImu);
    EXPECT_EQ(imu.received, 15000);
    // All of them, but those that came before the filter started (0.5 s of them in the late case) or, for the
    // stale case, none; every sample accounted for.
    EXPECT_GT(imu.*c.reason, 14850);
    const auto s = last_status(bus);
    EXPECT_EQ(imu.stale + imu.future + imu.late + imu.before_init + s.fused[0], 15000);
    EXPECT_EQ(s.stale[0], imu.stale);
    EXPECT_EQ(s.late[0], imu.late);
    EXPECT_EQ(s.future[0], imu.future);
    bool warned = false;
    for (const auto& w : est.counters().warnings) warned |= w.find("imu measurements rejected") != std::string::npos;
    EXPECT_TRUE(warned);
    // The other sensors are on the right clock: none of them is stale, late or from the future.
    for (int i = 1; i < 4; ++i) EXPECT_EQ(s.stale[i] + s.future[i] + s.late[i], 0) << s.input[i];
  }
}

// The first fix is the local frame's origin for the whole run. A fix off the globe (finite numbers, so the filter's
// own NaN check let it by) became that origin before: every later fix was NaN in it, and the position was lost for
// the whole flight. Now it is dropped and counted, and the next good fix is the origin.
TEST(DroneEstimatorModule, AFixOffTheGlobeIsNotTheOrigin) {
  DroneEstimatorModule est(config());
  driftlab::test::FakeBus bus;
  bus.add(est);
  ASSERT_TRUE(bus.start());
  driftlab::gnss_t bad{};
  bad.header = header(kT0 - 100000);
  bad.fix_type = 3;
  bad.latitude_deg = 1e300;
  bad.longitude_deg = 8.5;
  bad.eph_m = bad.epv_m = 1;
  ASSERT_TRUE(bus.deliver_message("GNSS", bad, Time::from_us(kT0 - 100000)));
  bad.latitude_deg = 47.4;
  bad.longitude_deg = -400;
  ASSERT_TRUE(bus.deliver_message("GNSS", bad, Time::from_us(kT0 - 50000)));
  Eigen::Vector3d origin;
  ASSERT_TRUE(play(bus, 0, &origin));
  ASSERT_TRUE(bus.finish());
  EXPECT_LT(worst_error(bus, origin), 0.6);
  const auto w = est.counters().warnings;
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("2 inputs"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("GNSS: a fix off the globe (latitude 1e+300, longitude 8.5)"), std::string::npos) << w[0];
}

}  // namespace
}  // namespace driftlab::estimator
