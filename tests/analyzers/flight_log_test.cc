// The flight-log diagnosis (analyzers/flight_log.h): on the shared real PX4 flight logs (../shared/data/ulog, with
// what pyulog finds in expected.json), and on flight logs written here with known faults injected (logger dropouts,
// an IMU scheduler that skips, a sensor publishing late, test ratios over 1, rejection and timeout flags, time
// slip; a companion's timesync reset, judged by the timing diagnosis), each threshold checked with a fault on either
// side of it; and on hostile logs (formats with fields missing or of other types, messages cut short, schemas that do
// not resolve).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "analyzers/flight_log.h"
#include "analyzers/timing.h"
#include "core/log_writer.h"
#include "driftlab/dropout_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/imu_t.hpp"
#include "formats/import.h"
#include "tests/formats/ulog_writer.h"
#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

using test::f32;
using test::put;
using test::Ulog;

/// Imports a ULog into dir and diagnoses its flight.
FlightLogDiagnosis diagnose_ulog(const std::string& ulg, const test::TempDir& dir) {
  const std::string lcm = dir.file("flight.lcm");
  auto s = formats::import_log(ulg, lcm, [](const std::string&) {});
  EXPECT_TRUE(s) << (s ? "" : s.error().message);
  auto d = diagnose_flight_log(lcm);
  EXPECT_TRUE(d) << (d ? "" : d.error().message);
  return d ? *d : FlightLogDiagnosis{};
}

bool has_problem(const FlightLogDiagnosis& d, const std::string& part) {
  return std::any_of(d.problems.begin(), d.problems.end(),
                     [&](const std::string& p) { return p.find(part) != std::string::npos; });
}

std::string all_problems(const FlightLogDiagnosis& d) {
  std::string s;
  for (const auto& p : d.problems) s += "\n  " + p;
  return s;
}

const ImuIntervals* imu(const FlightLogDiagnosis& d, const std::string& channel) {
  for (const auto& i : d.imu)
    if (i.channel == channel) return &i;
  return nullptr;
}
const SampleDelay* delay(const FlightLogDiagnosis& d, const std::string& channel) {
  for (const auto& s : d.sample_delays)
    if (s.channel == channel) return &s;
  return nullptr;
}
const EstimatorCheck* check(const FlightLogDiagnosis& d, const std::string& channel, const std::string& field) {
  for (const auto& s : d.estimator)
    if (s.channel == channel && s.field == field) return &s;
  return nullptr;
}

// ---- the shared real flight logs ----

nlohmann::json expected() {
  const std::string path = test::shared_data("ulog/expected.json");
  if (path.empty()) return nullptr;
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST(FlightLog, DropoutsOfTheSharedLogsAreThosePyulogFinds) {
  const auto want = expected();
  if (want.is_null()) return;
  for (const auto& [file, e] : want.items()) {
    SCOPED_TRACE(file);
    test::TempDir dir;
    const auto d = diagnose_ulog(test::shared_data("ulog/" + file), dir);
    ASSERT_TRUE(d.present);
    ASSERT_EQ(d.dropout_count, static_cast<int64_t>(e["dropouts"].size()));
    ASSERT_EQ(d.dropouts.size(), e["dropouts"].size());
    double total_ms = 0, max_ms = 0;
    for (size_t i = 0; i < d.dropouts.size(); ++i) {
      const auto& x = e["dropouts"][i];
      EXPECT_NEAR(d.dropouts[i].duration_s * 1e3, x["duration_ms"].get<double>(), 1e-9);
      // Where: the dropout's time (pyulog's: the latest timestamp before it) from the log's start.
      EXPECT_NEAR(d.dropouts[i].at_s * 1e6 + static_cast<double>(d.start_utime), x["timestamp_us"].get<double>(), 1);
      total_ms += x["duration_ms"].get<double>();
      max_ms = std::max(max_ms, x["duration_ms"].get<double>());
    }
    EXPECT_NEAR(d.dropout_total_s * 1e3, total_ms, 1e-9);
    EXPECT_NEAR(d.dropout_max_s * 1e3, max_ms, 1e-9);
    // Any dropout is a problem (threshold 1): it is data missing from every topic at once.
    EXPECT_EQ(has_problem(d, "the logger's buffer overflowed"), !e["dropouts"].empty()) << all_problems(d);
  }
}

TEST(FlightLog, CubeOrangeFlightIsHealthyButForItsDropoutAndTheLoggersStartingStall) {
  const std::string path = test::shared_data("ulog/sample_log_small.ulg");
  if (path.empty()) return;
  test::TempDir dir;
  const auto d = diagnose_ulog(path, dir);
  ASSERT_TRUE(d.present);
  // sensor_combined as the log holds it (imu_t, its stamp the gyro's sample time): a steady ~5 ms period.
  const ImuIntervals* sc = imu(d, "sensor_combined");
  ASSERT_NE(sc, nullptr);
  EXPECT_EQ(sc->intervals, 1297);  // pyulog's 1298 messages
  EXPECT_GT(sc->share_1x, 0.99);
  EXPECT_LT(sc->share_2x + sc->share_0, 0.05);
  EXPECT_FALSE(has_problem(d, "scheduler skips")) << all_problems(d);
  // Three IMUs' vehicle_imu, logged twice a second, with timestamp_sample: published under 1 ms after sampling.
  for (const char* c : {"vehicle_imu/0", "vehicle_imu/1", "vehicle_imu/2", "sensor_gyro/0", "sensor_accel/2"}) {
    const SampleDelay* s = delay(d, c);
    ASSERT_NE(s, nullptr) << c;
    EXPECT_TRUE(s->sensor);
    EXPECT_GT(s->p50_s, 0);
    EXPECT_LT(s->max_s, 0.001) << c;
  }
  // The PX4 1.11 estimator: estimator_innovation_test_ratios (its own topic) and estimator_status' ratios, all
  // under 1 on this flight (the highest 0.35): no rejection.
  const EstimatorCheck* gps = check(d, "estimator_innovation_test_ratios", "gps_hpos[0]");
  ASSERT_NE(gps, nullptr);
  EXPECT_EQ(gps->samples, 33);
  EXPECT_EQ(gps->over, 0);
  for (const auto& s : d.estimator) EXPECT_LT(s.max, 1.0) << s.channel << " " << s.field;
  EXPECT_FALSE(has_problem(d, "rejected")) << all_problems(d);
  // Every sensor stops at once 160 ms after the first samples, with no dropout recorded: said once, as a stall of
  // the log, not as a gap of each sensor.
  EXPECT_TRUE(has_problem(d, "nothing from most sensors")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "stopped publishing")) << all_problems(d);
  // The timeline: the dropout and the stall.
  EXPECT_TRUE(
      std::any_of(d.timeline.begin(), d.timeline.end(), [](const FlightEvent& e) { return e.kind == "dropout"; }));
}

TEST(FlightLog, SitlFlightShowsTheSkippingSchedulerAndThreeEstimators) {
  const std::string path = test::shared_data("ulog/sample_logging_tagged_and_default_params.ulg");
  if (path.empty()) return;
  test::TempDir dir;
  const auto d = diagnose_ulog(path, dir);
  ASSERT_TRUE(d.present);
  // SITL's sensor_combined: a 4 ms period, one interval in three of 8 ms: the pattern of a scheduler that skips.
  const ImuIntervals* sc = imu(d, "sensor_combined");
  ASSERT_NE(sc, nullptr);
  EXPECT_NEAR(sc->nominal_s, 0.004, 1e-6);
  EXPECT_NEAR(sc->share_2x, 0.33, 0.02);
  EXPECT_TRUE(has_problem(d, "sensor_combined's scheduler skips cycles")) << all_problems(d);
  // EKF2 stamps its outputs with its delayed fusion horizon's sample time: 80 ms behind here.
  EXPECT_NEAR(d.horizon_s, 0.080, 1e-6);
  // Three estimator instances, each with its test ratios (PX4 1.12's topic, with timestamp_sample) and status.
  for (const char* c : {"estimator_innovation_test_ratios/0", "estimator_innovation_test_ratios/1",
                        "estimator_innovation_test_ratios/2"}) {
    const EstimatorCheck* s = check(d, c, "baro_vpos");
    ASSERT_NE(s, nullptr) << c;
    EXPECT_EQ(s->over, 0);
  }
  EXPECT_EQ(check(d, "estimator_innovation_test_ratios/0", "baro_vpos")->samples, 1279);
  ASSERT_NE(check(d, "estimator_status/2", "mag_test_ratio"), nullptr);
  // No dropouts.
  EXPECT_EQ(d.dropout_count, 0);
}

TEST(FlightLog, AppendedDataFlightHasA4MsImu) {
  const std::string path = test::shared_data("ulog/sample_appended_multiple.ulg");
  if (path.empty()) return;
  test::TempDir dir;
  const auto d = diagnose_ulog(path, dir);
  ASSERT_TRUE(d.present);
  const ImuIntervals* sc = imu(d, "sensor_combined");
  ASSERT_NE(sc, nullptr);
  EXPECT_NEAR(sc->nominal_s, 0.004, 5e-6);
  EXPECT_GT(sc->share_1x, 0.99);
  // An old PX4's estimator_status (no estimator_innovation_test_ratios topic then): its *_test_ratio fields.
  ASSERT_NE(check(d, "estimator_status", "hgt_test_ratio"), nullptr);
  EXPECT_EQ(check(d, "estimator_status", "hgt_test_ratio")->samples, 48);
}

// ---- a flight written here, faults injected at known times ----

struct Faults {
  bool skips = true;       // gyro/0's scheduler runs late and catches up: 2 of ~10 intervals in 8 (8 ms, 0 ms)
  bool late_accel = true;  // sensor_accel published 30 ms after sampling (over the IMU's 20 ms)
  bool late_mag = true;    // sensor_mag published 150 ms after sampling (over EKF2's 110 ms default horizon)
  bool dropout = true;     // the logger loses 300 ms at 1.0 s
  bool stall = true;       // no sensor logged from 2.5 s to 2.8 s, and no dropout recorded
  bool own_gap = true;     // gyro/0 silent from 3.0 s to 3.1 s (25 periods), the others going on
  bool rejections = true;  // baro_vpos' test ratio 1.5 from 1.5 s to 3.0 s; innovation_check_flags' bit 2 too
  bool timeout = true;     // gps_fusion_timout at 2 s
  bool slip = true;        // time_slip grows by 20 ms
  bool slow_link = true;   // 4 of 40 timesync round trips of 15 ms, and the offset reset once
};

/// Four seconds of a flight. Every sample lies on a 4 ms grid from 0.1 s; times in microseconds.
std::vector<uint8_t> flight(const Faults& f) {
  Ulog u(100000);
  u.flags(0);
  u.format("sensor_gyro:uint64_t timestamp;uint64_t timestamp_sample;float x;");
  u.format("sensor_accel:uint64_t timestamp;uint64_t timestamp_sample;float x;");
  u.format("sensor_baro:uint64_t timestamp;uint64_t timestamp_sample;float x;");
  u.format("sensor_mag:uint64_t timestamp;uint64_t timestamp_sample;float x;");
  u.format("estimator_innovation_test_ratios:uint64_t timestamp;float[2] gps_hpos;float baro_vpos;");
  u.format(
      "estimator_status:uint64_t timestamp;float vel_test_ratio;float time_slip;uint16_t innovation_check_flags;"
      "uint8_t timeout_flags;");
  u.format("estimator_event_flags:uint64_t timestamp;bool gps_fusion_timout;bool reset_vel_to_gps;");
  u.format(
      "timesync_status:uint64_t timestamp;uint64_t remote_timestamp;int64_t observed_offset;int64_t "
      "estimated_offset;uint32_t round_trip_time;");
  u.subscribe(0, 1, "sensor_gyro");
  u.subscribe(1, 2, "sensor_gyro");
  u.subscribe(0, 3, "sensor_accel");
  u.subscribe(0, 4, "sensor_baro");
  u.subscribe(0, 5, "sensor_mag");
  u.subscribe(0, 10, "estimator_innovation_test_ratios");
  u.subscribe(0, 11, "estimator_status");
  u.subscribe(0, 12, "estimator_event_flags");
  u.subscribe(0, 13, "timesync_status");
  struct Message {
    uint64_t t;  // timestamp: when published [us]
    uint16_t id;
    std::vector<uint8_t> body;
  };
  std::vector<Message> m;
  auto in = [](uint64_t t, double a_s, double b_s) { return t >= a_s * 1e6 && t < b_s * 1e6; };
  auto sensor = [&](uint16_t id, uint64_t sample, uint64_t delay_us, bool is_gyro0) {
    const uint64_t t = sample + delay_us;
    if (f.dropout && in(t, 1.0, 1.3)) return;  // lost with the logger's buffer
    if (f.stall && in(t, 2.5, 2.8)) return;
    if (is_gyro0 && f.own_gap && in(t, 3.0, 3.1)) return;
    std::vector<uint8_t> b;
    put(b, t, 8);
    put(b, sample, 8);
    const auto x = f32(1.0f);
    b.insert(b.end(), x.begin(), x.end());
    m.push_back({t, id, b});
  };
  for (int k = 0; k < 975; ++k) {
    const uint64_t grid = 100000 + 4000 * static_cast<uint64_t>(k);
    // gyro/0: every 10th sample from the 100th published a period late, with the next (an 8 ms interval, then 0).
    const bool late = f.skips && k >= 100 && k % 10 == 0;
    sensor(1, grid + (late ? 4000 : 0), 500, true);
    // gyro/1: one sample in 50 lost (2% of intervals at two periods: under the 5% threshold).
    if (k % 50 != 25) sensor(2, grid, 500, false);
    sensor(3, grid, f.late_accel ? 30000 : 500, false);
    if (k % 25 == 0) {
      sensor(4, grid, 60000, false);  // a barometer at 10 Hz, 60 ms late: under the 110 ms horizon
      sensor(5, grid, f.late_mag ? 150000 : 1000, false);
    }
  }
  for (int k = 1; k <= 39; ++k) {  // the estimator at 10 Hz
    const uint64_t t = 100000 * static_cast<uint64_t>(k);
    const bool rejecting = f.rejections && in(t, 1.5, 3.0);  // 15 samples: 1.5 s over 1
    const bool brief = in(t, 0.5, 0.8);                      // 3 samples: 0.3 s over 1, under the 1 s threshold
    std::vector<uint8_t> r;
    put(r, t, 8);
    for (float v : {0.3f, brief ? 1.2f : 0.4f, rejecting ? 1.5f : 0.2f}) {
      const auto x = f32(v);
      r.insert(r.end(), x.begin(), x.end());
    }
    m.push_back({t, 10, r});
    std::vector<uint8_t> s;
    put(s, t, 8);
    for (float v : {0.2f, f.slip ? 0.020f * static_cast<float>(k - 1) / 38 : 0.0f}) {
      const auto x = f32(v);
      s.insert(s.end(), x.begin(), x.end());
    }
    put(s, rejecting ? 1u << 2 : 0u, 2);  // bit 2: vertical position rejected
    put(s, 0, 1);
    m.push_back({t, 11, s});
    if (k % 10 == 0) {
      std::vector<uint8_t> e;
      put(e, t, 8);
      put(e, f.timeout && t == 2000000 ? 1 : 0, 1);
      put(e, 0, 1);
      m.push_back({t, 12, e});
    }
    std::vector<uint8_t> ts;
    put(ts, t, 8);
    put(ts, t + 5000000, 8);
    const int64_t offset = f.slow_link && t >= 2000000 ? 51000 : 1000;
    put(ts, static_cast<uint64_t>(offset), 8);
    put(ts, static_cast<uint64_t>(offset), 8);
    put(ts, f.slow_link && k % 10 == 3 ? 15000 : 2000, 4);
    m.push_back({t, 13, ts});
  }
  std::stable_sort(m.begin(), m.end(), [](const Message& a, const Message& b) { return a.t < b.t; });
  bool dropped = false;
  for (const auto& x : m) {
    if (f.dropout && !dropped && x.t >= 1000000) {
      u.dropout(300);
      dropped = true;
    }
    u.data_bytes(x.id, x.body);
  }
  return u.b;
}

FlightLogDiagnosis diagnose_flight(const Faults& f) {
  test::TempDir dir;
  test::write_file(dir.file("flight.ulg"), flight(f));
  return diagnose_ulog(dir.file("flight.ulg"), dir);
}

TEST(FlightLog, InjectedFaultsAreEachFoundAndNamed) {
  const auto d = diagnose_flight(Faults{});
  ASSERT_TRUE(d.present);
  // The dropout: one, 300 ms, at the latest time before it (0.998 s: the accelerometer's sample of 0.968 s,
  // published 30 ms after).
  EXPECT_EQ(d.dropout_count, 1);
  EXPECT_NEAR(d.dropout_total_s, 0.3, 1e-9);
  EXPECT_NEAR(d.dropout_max_s, 0.3, 1e-9);
  ASSERT_EQ(d.dropouts.size(), 1u);
  EXPECT_NEAR(d.dropouts[0].at_s * 1e6 + static_cast<double>(d.start_utime), 998000, 1);
  EXPECT_TRUE(has_problem(d, "the logger's buffer overflowed: 1 dropout, 300 ms")) << all_problems(d);

  // The skipping scheduler: 86 late samples of gyro/0, each an 8 ms and a 0 ms interval: 18% of its intervals,
  // over the 5% threshold. gyro/1 loses one sample in 50 (2% of its intervals at 8 ms): under it.
  const ImuIntervals* g0 = imu(d, "sensor_gyro/0");
  const ImuIntervals* g1 = imu(d, "sensor_gyro/1");
  ASSERT_NE(g0, nullptr);
  ASSERT_NE(g1, nullptr);
  EXPECT_NEAR(g0->nominal_s, 0.004, 1e-9);
  EXPECT_GT(g0->share_2x, 0.07);
  EXPECT_GT(g0->share_0, 0.07);
  EXPECT_NEAR(g1->share_2x, 0.02, 0.005);
  EXPECT_TRUE(has_problem(d, "sensor_gyro/0's scheduler skips cycles")) << all_problems(d);
  EXPECT_TRUE(has_problem(d, "catches up by publishing two samples at once")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "sensor_gyro/1's scheduler")) << all_problems(d);

  // Sample to publication: the accelerometer's 30 ms is over an IMU's 20 ms; the gyros' 0.5 ms is not; the
  // barometer's 60 ms is under EKF2's default 110 ms horizon, the magnetometer's 150 ms over it.
  EXPECT_NEAR(delay(d, "sensor_accel")->p99_s, 0.030, 1e-9);
  EXPECT_NEAR(delay(d, "sensor_gyro/0")->p99_s, 0.0005, 1e-9);
  EXPECT_TRUE(has_problem(d, "sensor_accel publishes its samples late: 30.0 ms")) << all_problems(d);
  EXPECT_TRUE(has_problem(d, "sensor_mag publishes its samples late: 150.0 ms")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "sensor_gyro/0 publishes")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "sensor_baro publishes")) << all_problems(d);

  // Gaps: the dropout's are the logger's, the stall at 2.5 s every sensor's at once (said once), and gyro/0's own
  // 100 ms at 3.0 s the sensor's.
  EXPECT_TRUE(has_problem(d, "nothing from most sensors 1 time")) << all_problems(d);
  EXPECT_TRUE(has_problem(d, "sensor_gyro/0 stopped publishing 1 time")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "sensor_gyro/1 stopped")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "sensor_accel stopped")) << all_problems(d);
  // Whether an event of this kind covers at_s (of the flight controller's clock; the timeline's times are from the
  // log's start, the header's 0.1 s).
  auto on_timeline = [&](const std::string& kind, const std::string& what, double clock_s) {
    const double at_s = clock_s - static_cast<double>(d.start_utime) * 1e-6;
    return std::any_of(d.timeline.begin(), d.timeline.end(), [&](const FlightEvent& e) {
      return e.kind == kind && e.what.find(what) != std::string::npos && e.start_s <= at_s && e.end_s >= at_s;
    });
  };
  EXPECT_TRUE(on_timeline("dropout", "logger", 1.0));
  EXPECT_TRUE(on_timeline("sensor_gap", "sensor_gyro/1 (at a logger dropout)", 1.1));
  EXPECT_TRUE(on_timeline("sensor_gap", "every sensor at once", 2.6));
  EXPECT_TRUE(on_timeline("sensor_gap", "sensor_gyro/0", 3.05));

  // Test ratios: baro_vpos over 1 for 1.5 s (over the 1 s threshold); gps_hpos[1] for 0.3 s (under it, counted).
  const EstimatorCheck* baro = check(d, "estimator_innovation_test_ratios", "baro_vpos");
  const EstimatorCheck* gps = check(d, "estimator_innovation_test_ratios", "gps_hpos[1]");
  ASSERT_NE(baro, nullptr);
  ASSERT_NE(gps, nullptr);
  EXPECT_EQ(baro->over, 15);
  EXPECT_NEAR(baro->time_over_s, 1.5, 1e-9);
  EXPECT_NEAR(baro->max, 1.5, 1e-6);
  EXPECT_NEAR(baro->first_s * 1e6 + static_cast<double>(d.start_utime), 1.5e6, 1);
  EXPECT_EQ(gps->over, 3);
  EXPECT_NEAR(gps->time_over_s, 0.3, 1e-9);
  EXPECT_TRUE(has_problem(d, "the estimator rejected baro_vpos")) << all_problems(d);
  EXPECT_FALSE(has_problem(d, "rejected gps_hpos")) << all_problems(d);
  // The same rejection as estimator_status' innovation_check_flags (the log has no estimator_status_flags).
  EXPECT_TRUE(has_problem(d, "rejected innovation_check_flags: vertical position")) << all_problems(d);
  EXPECT_TRUE(on_timeline("rejection", "baro_vpos", 2.0));
  // The timeout and time slip.
  EXPECT_TRUE(has_problem(d, "the estimator timed out on gps_fusion_timout")) << all_problems(d);
  EXPECT_TRUE(on_timeline("timeout", "gps_fusion_timout", 2.0));
  EXPECT_TRUE(has_problem(d, "fell 20 ms behind the IMU")) << all_problems(d);
  // The companion's timesync_status is the timing diagnosis' (CompanionTimesyncIsJudgedAsEveryTimeSync), not this.
  EXPECT_FALSE(has_problem(d, "timesync")) << all_problems(d);
}

// PX4's timesync_status is imported as driftlab.timesync_status_t, so the timing diagnosis judges it as it judges
// MAVROS's: the same offsets, round trips and resyncs as the flight wrote (1 ms, then 51 ms from 2.0 s: one resync;
// round trips of 2 ms, 4 of 39 of 15 ms).
TEST(FlightLog, CompanionTimesyncIsJudgedAsEveryTimeSync) {
  for (const bool slow_link : {true, false}) {
    SCOPED_TRACE(slow_link ? "offset reset" : "steady link");
    Faults f;
    f = {false, false, false, false, false, false, false, false, false, slow_link};
    test::TempDir dir;
    test::write_file(dir.file("flight.ulg"), flight(f));
    const std::string lcm = dir.file("flight.lcm");
    ASSERT_TRUE(formats::import_log(dir.file("flight.ulg"), lcm, [](const std::string& p) { ADD_FAILURE() << p; }));
    const auto d = diagnose(lcm);
    ASSERT_TRUE(d) << d.error().message;
    ASSERT_EQ(d->timesync.size(), 1u);
    const TimesyncTiming& t = d->timesync[0];
    EXPECT_EQ(t.channel, "timesync_status");
    EXPECT_EQ(t.messages, 39);
    EXPECT_NEAR(t.offset_first_s, 0.001, 1e-12);
    EXPECT_NEAR(t.offset_last_s, slow_link ? 0.051 : 0.001, 1e-12);
    EXPECT_NEAR(t.round_trip_s.p50, 0.002, 1e-12);
    EXPECT_NEAR(t.round_trip_s.max, slow_link ? 0.015 : 0.002, 1e-12);
    EXPECT_NEAR(t.residual_s.max, 0, 1e-12);  // observed = estimated in every exchange written
    EXPECT_EQ(t.resyncs, slow_link ? 1 : 0);
    if (slow_link) {
      ASSERT_EQ(t.resync_at_s.size(), 1u);
      // The step is at the sample of 2.0 s; the log starts at its first message, the sample of 0.1 s.
      EXPECT_NEAR(t.resync_at_s[0] + static_cast<double>(d->start_utime) * 1e-6, 2.0, 1e-9);
    }
    const auto c = std::find_if(d->channels.begin(), d->channels.end(),
                                [](const ChannelTiming& x) { return x.name == "timesync_status"; });
    ASSERT_NE(c, d->channels.end());
    const bool reason = std::any_of(c->reasons.begin(), c->reasons.end(), [](const auto& r) {
      return r.find("time sync started over 1 times") != std::string::npos;
    });
    EXPECT_EQ(reason, slow_link);
  }
}

TEST(FlightLog, CleanFlightHasNoProblems) {
  Faults none;
  none = {false, false, false, false, false, false, false, false, false, false};
  const auto d = diagnose_flight(none);
  ASSERT_TRUE(d.present);
  EXPECT_TRUE(d.problems.empty()) << all_problems(d);
  EXPECT_EQ(d.dropout_count, 0);
  EXPECT_GT(imu(d, "sensor_gyro/0")->share_1x, 0.999);
  // Rejections under the threshold still go on the timeline (gps_hpos[1] at 0.5 s), nothing else does.
  for (const auto& e : d.timeline) EXPECT_EQ(e.kind, "rejection") << e.what;
}

TEST(FlightLog, NewerEstimatorFlagsAreReadInsteadOfTheBitmask) {
  // PX4 1.12 and later say which fusion was rejected in estimator_status_flags' reject_* fields; its
  // innovation_check_flags would say it twice.
  Ulog u(0);
  u.flags(0);
  u.format("estimator_status:uint64_t timestamp;uint16_t innovation_check_flags;");
  u.format("estimator_status_flags:uint64_t timestamp;bool cs_gps;bool reject_hor_pos;bool reject_yaw;");
  u.subscribe(0, 1, "estimator_status");
  u.subscribe(0, 2, "estimator_status_flags");
  for (int k = 1; k <= 50; ++k) {
    const uint64_t t = 100000 * static_cast<uint64_t>(k);
    const bool bad = k >= 10 && k < 30;  // 2 s rejected
    std::vector<uint8_t> s;
    put(s, t, 8);
    put(s, bad ? 2u : 0u, 2);
    u.data_bytes(1, s);
    std::vector<uint8_t> f;
    put(f, t, 8);
    put(f, 1, 1);
    put(f, bad ? 1 : 0, 1);
    put(f, 0, 1);
    u.data_bytes(2, f);
  }
  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  const auto d = diagnose_ulog(dir.file("f.ulg"), dir);
  const EstimatorCheck* hor = check(d, "estimator_status_flags", "reject_hor_pos");
  ASSERT_NE(hor, nullptr);
  EXPECT_EQ(hor->over, 20);
  EXPECT_NEAR(hor->time_over_s, 2.0, 1e-9);
  EXPECT_TRUE(has_problem(d, "rejected reject_hor_pos")) << all_problems(d);
  EXPECT_EQ(check(d, "estimator_status", "innovation_check_flags: horizontal position"), nullptr);
  EXPECT_FALSE(has_problem(d, "innovation_check_flags")) << all_problems(d);
}

// ---- hostile logs ----

TEST(FlightLog, FieldsOfOtherTypesOrMissingAreSkipped) {
  // The watched topics with their fields of other types (a test ratio as chars, times as floats, an offset as a
  // bool), arrays where scalars are read, and fields missing: read without a crash, and nothing made up.
  Ulog u(0);
  u.flags(0);
  u.format("estimator_innovation_test_ratios:uint64_t timestamp;char[4] gps_hpos;uint8_t baro_vpos;");
  u.format("sensor_gyro:float timestamp;uint8_t timestamp_sample;");
  u.format("estimator_status:uint64_t timestamp;float[3] time_slip;double innovation_check_flags;");
  u.format("timesync_status:uint64_t timestamp;bool estimated_offset;");
  u.format("vehicle_imu_status:uint64_t timestamp;float accel_error_count;");
  u.subscribe(0, 1, "estimator_innovation_test_ratios");
  u.subscribe(0, 2, "sensor_gyro");
  u.subscribe(0, 3, "estimator_status");
  u.subscribe(0, 4, "timesync_status");
  u.subscribe(0, 5, "vehicle_imu_status");
  for (int k = 1; k <= 30; ++k) {
    const uint64_t t = 100000 * static_cast<uint64_t>(k);
    std::vector<uint8_t> a;
    put(a, t, 8);
    a.insert(a.end(), {'9', '9', '9', '9', 200});
    u.data_bytes(1, a);
    std::vector<uint8_t> g = f32(static_cast<float>(t));
    g.push_back(7);
    u.data_bytes(2, g);
    std::vector<uint8_t> s;
    put(s, t, 8);
    for (int i = 0; i < 3; ++i) {
      const auto x = f32(static_cast<float>(k));
      s.insert(s.end(), x.begin(), x.end());
    }
    put(s, 0xffffffffffffffffull, 8);
    u.data_bytes(3, s);
    std::vector<uint8_t> ts;
    put(ts, t, 8);
    ts.push_back(1);
    u.data_bytes(4, ts);
    std::vector<uint8_t> v;
    put(v, t, 8);
    const auto x = f32(static_cast<float>(k));
    v.insert(v.end(), x.begin(), x.end());
    u.data_bytes(5, v);
  }
  test::TempDir dir;
  test::write_file(dir.file("f.ulg"), u.b);
  const auto d = diagnose_ulog(dir.file("f.ulg"), dir);
  ASSERT_TRUE(d.present);
  EXPECT_EQ(check(d, "estimator_innovation_test_ratios", "gps_hpos[0]"), nullptr);  // chars: not a ratio
  EXPECT_EQ(check(d, "estimator_innovation_test_ratios", "baro_vpos"), nullptr);    // an integer: not a ratio
  EXPECT_EQ(delay(d, "sensor_gyro"), nullptr);  // no uint64_t timestamp and timestamp_sample
  EXPECT_TRUE(d.imu_loss.empty());              // time_slip an array, the error count a float
  EXPECT_TRUE(d.problems.empty()) << all_problems(d);
}

TEST(FlightLog, DamagedRecordsInTheLogAreSkipped) {
  // An LCM log with ULog records no import would write: schemas that do not resolve or name another topic,
  // messages cut short, a negative dropout, bytes that are no message at all.
  test::TempDir dir;
  const std::string path = dir.file("hostile.lcm");
  {
    auto w = LogWriter::create(path);
    ASSERT_TRUE(w);
    auto schema = [&](const std::string& channel, const std::string& type, const std::string& definition) {
      foreign_schema_t s;
      s.channel = channel;
      s.type = type;
      s.encoding = "ulog";
      s.definition = definition;
      ASSERT_TRUE(w->write(0, "FOREIGN_SCHEMAS", test::encode(s)));
    };
    auto message = [&](int64_t t, const std::string& channel, const std::string& type, std::vector<uint8_t> data) {
      foreign_message_t m;
      m.type = type;
      m.encoding = "ulog";
      m.data = std::move(data);
      m.size = static_cast<int32_t>(m.data.size());
      ASSERT_TRUE(w->write(t, channel, test::encode(m)));
    };
    schema("a", "estimator_innovation_test_ratios",
           "estimator_innovation_test_ratios:uint64_t timestamp;float[2] gps_hpos;");
    schema("b", "sensor_gyro", "::::\n:\nsensor_gyro:uint64_t timestamp;nested_t n;");  // an unknown nested type
    schema("c", "timesync_status", "");
    schema("d", "sensor_accel", "sensor_accel:uint64_t timestamp;uint64_t timestamp_sample;float[1000000] x;");
    for (int k = 1; k <= 20; ++k) {
      const int64_t t = int64_t{100000} * k;
      std::vector<uint8_t> cut;
      put(cut, static_cast<uint64_t>(t), 8);
      cut.push_back(0x40);  // a float cut after its first byte
      message(t, "a", "estimator_innovation_test_ratios", cut);
      message(t, "a", "sensor_gyro", cut);  // another topic than its channel's schema
      message(t, "b", "sensor_gyro", cut);
      message(t, "c", "timesync_status", {});
      message(t, "d", "sensor_accel", cut);
      message(t, "e", "sensor_mag", cut);  // no schema at all
      ASSERT_TRUE(w->write(t, "ULOG_DROPOUTS", std::vector<uint8_t>{1, 2, 3}));
      dropout_t o;
      o.header.seq = k;
      o.header.utime = t;
      o.header.frame_id = "";
      o.duration_us = -5;
      ASSERT_TRUE(w->write(t, "ULOG_DROPOUTS", test::encode(o)));
      // sensor_combined as imported (imu_t) with stamps at int64_t's ends: no difference of them may overflow.
      imu_t m{};
      m.header.seq = k;
      m.header.utime = k % 2 ? INT64_MIN : INT64_MAX;
      m.header.frame_id = "body_frd";
      ASSERT_TRUE(w->write(k % 2 ? INT64_MAX : t, "sensor_combined", test::encode(m)));
    }
    ASSERT_TRUE(w->close());
  }
  auto d = diagnose_flight_log(path);
  ASSERT_TRUE(d);
  EXPECT_TRUE(d->present);
  EXPECT_EQ(d->dropout_count, 0);
  // The cut float reads as nothing: a ratio series with no sample is left out.
  EXPECT_EQ(check(*d, "a", "gps_hpos[0]"), nullptr);
  EXPECT_TRUE(d->problems.empty()) << all_problems(*d);
}

TEST(FlightLog, LogWithoutUlogDataIsNotAFlightLog) {
  test::TempDir dir;
  const std::string path = dir.file("plain.lcm");
  {
    auto w = LogWriter::create(path);
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write(1, "SOMETHING", std::vector<uint8_t>{1, 2, 3, 4, 5, 6, 7, 8, 9}));
    ASSERT_TRUE(w->close());
  }
  auto d = diagnose_flight_log(path);
  ASSERT_TRUE(d);
  EXPECT_FALSE(d->present);
  EXPECT_TRUE(d->problems.empty());
  EXPECT_FALSE(diagnose_flight_log(dir.file("missing.lcm")));
}

}  // namespace
}  // namespace driftlab::analyzers
