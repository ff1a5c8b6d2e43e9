// Tests for analyzers/timing.h on synthetic logs with known faults: a robot turning with a varying yaw rate,
// observed by ground truth, an IMU and wheel odometry, plus a scan stream and an untyped stream; each stream
// with its own clock, latency and losses. Accuracy targets from the issue: drop counts exact, relative offsets
// from 2 to 200 ms within 1 ms, drift within 20 ppm, nothing flagged on a clean log.
#include "analyzers/timing.h"
#include "analyzers/diagnosis_json.h"
#include "analyzers/diagnosis_text.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "analyzers/clock_corrections.h"
#include "analyzers/internal/tf_check.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "driftlab/fault_manifest_t.hpp"
#include "driftlab/header_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "faults/faults.h"
#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

struct Faults {
  double imu_offset_s = 0;     // IMU stamps later than the truth by this much
  double odom_drift_ppm = 0;   // odometry clock running fast
  std::set<int64_t> scan_drops;
  std::set<int64_t> scan_duplicates;
  int64_t scan_reorder = -1;   // this scan arrives after the next one
  int raw_gap = 0;             // untyped messages missing in one gap
  // TF: odom -> base_link at 50 Hz (dynamic), world -> odom and base_link -> imu, laser (static, 1 Hz).
  double tf_delay_s = 0.001;   // how long after its stamp a dynamic transform arrives
  double tf_stops_at_s = 1e9;  // no dynamic transforms after this
  bool tf_future = false;      // dynamic transforms stamped 20 ms ahead of their arrival
  double tf_period_s = 0.02;   // the dynamic transform's period
  double tf_stamp_offset_s = 0;  // added to the dynamic transform's stamps (its clock)
  bool laser_static_missing = false;
  bool static_changes = false; // base_link -> imu republished with another offset
  std::string static_channel = "TF_STATIC";
  bool static_once = false;     // the static transforms published once, at the start (ROS's latched /tf_static)
  bool copy_truth = false;      // POSE: the ground truth's poses again, with its stamps (as a pose logged with a scan)
  bool trajectory_at_end = false;  // TRAJECTORY: the ground truth's poses again, all written at the end (a SLAM's)
};

constexpr int64_t kT0 = 1763776800000000;
constexpr double kSeconds = 60;

double yaw_rate(double t) { return 0.5 * std::sin(0.7 * t) + 0.3 * std::sin(1.9 * t + 1); }
double yaw(double t) { return -0.5 / 0.7 * std::cos(0.7 * t) - 0.3 / 1.9 * std::cos(1.9 * t + 1); }

/// A message as it reaches the logger.
struct Arrival {
  int64_t utime;
  std::string channel;
  std::vector<uint8_t> data;
};

/// Writes a log of the messages in the order they arrive, as a logger would.
void write_in_arrival_order(const std::string& path, std::vector<Arrival> out) {
  std::stable_sort(out.begin(), out.end(), [](const Arrival& a, const Arrival& b) { return a.utime < b.utime; });
  auto w = LogWriter::create(path);
  ASSERT_TRUE(w.ok());
  for (const auto& a : out) ASSERT_TRUE(w->write(a.utime, a.channel, a.data).ok());
  ASSERT_TRUE(w->close().ok());
}

template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

void write_log(const std::string& path, const Faults& f, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  std::exponential_distribution<double> jitter(1 / 0.0002);
  std::vector<Arrival> out;
  auto us = [](double s) { return static_cast<int64_t>(std::llround(s * 1e6)); };
  for (int64_t i = 0; i * 0.01 <= kSeconds; ++i) {  // ground truth, 100 Hz, true clock
    const double t = i * 0.01;
    driftlab::pose_t m{};
    m.header = {i, kT0 + us(t), "world"};
    m.orientation = {std::cos(yaw(t) / 2), 0, 0, std::sin(yaw(t) / 2)};
    out.push_back({kT0 + us(t) + 100, "GROUND_TRUTH", encode(m)});
    if (f.copy_truth) out.push_back({kT0 + us(t) + 300, "POSE", encode(m)});
    if (f.trajectory_at_end) out.push_back({kT0 + us(kSeconds) + 1000 + i, "TRAJECTORY", encode(m)});
  }
  for (int64_t i = 0; i * 0.005 <= kSeconds; ++i) {  // IMU, 200 Hz, its clock offset
    const double t = i * 0.005;
    driftlab::imu_t m{};
    m.header = {i, kT0 + us(t + f.imu_offset_s), "imu"};
    m.angular_velocity.z = yaw_rate(t) + 0.002 * noise(rng);
    out.push_back({kT0 + us(t + 0.0003 + jitter(rng)), "IMU", encode(m)});
  }
  for (int64_t i = 0; i * 0.02 <= kSeconds; ++i) {  // odometry, 50 Hz, its clock drifting
    const double t = i * 0.02;
    driftlab::odometry_t m{};
    m.header = {i, kT0 + us(t * (1 + f.odom_drift_ppm * 1e-6)), "odom"};
    m.angular_velocity.z = yaw_rate(t) + 0.005 * noise(rng);
    out.push_back({kT0 + us(t + 0.0008 + jitter(rng)), "ODOM", encode(m)});
  }
  for (int64_t i = 0; i * 0.1 <= kSeconds; ++i) {  // scans, 10 Hz, lossy
    if (f.scan_drops.count(i)) continue;
    const double t = i * 0.1;
    driftlab::laser_scan_t m{};
    m.header = {i, kT0 + us(t), "laser"};
    m.nranges = 4;
    m.ranges = {1, 2, 3, 4};
    const double arrive = t + 0.004 + (i == f.scan_reorder ? 0.15 : 0.0);
    out.push_back({kT0 + us(arrive), "SCAN", encode(m)});
    if (f.scan_duplicates.count(i)) out.push_back({kT0 + us(arrive) + 50, "SCAN", encode(m)});
  }
  auto transform = [](const char* parent, const char* child, int64_t stamp, double x) {
    driftlab::transform_t t{};
    t.header = {0, stamp, parent};
    t.child_frame_id = child;
    t.translation = {x, 0, 0};
    t.rotation = {1, 0, 0, 0};
    return t;
  };
  for (int64_t i = 0; i * f.tf_period_s <= kSeconds && i * f.tf_period_s < f.tf_stops_at_s; ++i) {  // dynamic TF
    const double t = i * f.tf_period_s;
    driftlab::tf_t tf{};
    const int64_t stamp = kT0 + us(t + f.tf_stamp_offset_s) + (f.tf_future ? 20000 : 0);
    tf.header = {i, stamp, "odom"};
    tf.transforms = {transform("odom", "base_link", stamp, t)};
    tf.ntransforms = 1;
    out.push_back({kT0 + us(t + f.tf_delay_s), "TF", encode(tf)});
  }
  for (int64_t i = 0; i <= static_cast<int64_t>(kSeconds); ++i) {  // static TF, 1 Hz
    driftlab::tf_t tf{};
    tf.header = {i, kT0 + i * 1000000, "world"};
    tf.transforms = {transform("world", "odom", kT0, 0),
                     transform("base_link", "imu", kT0, f.static_changes && i > 30 ? 0.2 : 0.1)};
    if (!f.laser_static_missing) tf.transforms.push_back(transform("base_link", "laser", kT0, 0.3));
    tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
    out.push_back({kT0 + i * 1000000 + 500, f.static_channel, encode(tf)});
    if (f.static_once) break;
  }
  for (int i = 0; i * (1.0 / 30) <= kSeconds; ++i) {  // an untyped stream at 30 Hz
    if (i >= 300 && i < 300 + f.raw_gap) continue;
    std::vector<uint8_t> raw(16, static_cast<uint8_t>(i));
    raw[1] = static_cast<uint8_t>(i >> 8);
    out.push_back({kT0 + us(i / 30.0), "RAW", raw});
  }
  write_in_arrival_order(path, out);
}

const ChannelTiming& channel(const Diagnosis& d, const std::string& name) {
  for (const auto& c : d.channels)
    if (c.name == name) return c;
  ADD_FAILURE() << "no channel " << name;
  static ChannelTiming none;
  return none;
}

const StreamPair* pair(const Diagnosis& d, const std::string& a, const std::string& b) {
  for (const auto& p : d.pairs)
    if (p.a == a && p.b == b) return &p;
  return nullptr;
}

TEST(Diagnose, FlagsNothingOnACleanLog) {
  test::TempDir dir;
  write_log(dir.file("clean.lcm"), {}, 1);
  auto d = diagnose(dir.file("clean.lcm"));
  ASSERT_TRUE(d.ok()) << d.error().message;
  ASSERT_EQ(d->channels.size(), 7u);
  EXPECT_EQ(d->tf.frames, (std::vector<std::string>{"base_link", "imu", "laser", "odom", "world"}));
  EXPECT_EQ(d->tf.roots, (std::vector<std::string>{"world"}));
  EXPECT_TRUE(d->tf.problems.empty()) << d->tf.problems.front();
  for (const auto& c : d->channels) {
    EXPECT_EQ(c.verdict, "ok") << c.name << ": " << (c.reasons.empty() ? "" : c.reasons[0]);
  }
  EXPECT_NEAR(channel(*d, "IMU").rate_hz, 200, 0.5);
  EXPECT_NEAR(channel(*d, "SCAN").expected_period_s, 0.1, 1e-6);
  ASSERT_EQ(d->pairs.size(), 3u);
  for (const auto& p : d->pairs) {
    EXPECT_LT(std::abs(p.offset_s), 0.001) << p.a << " -> " << p.b;
    EXPECT_GT(p.confidence, 0.9) << p.a << " -> " << p.b;
  }
}

// A result written at once (a SLAM's trajectory as last optimised, written at the end: 60 s of stamps arriving
// within a millisecond) is no stream: no latency of a minute, no clock a million ppm fast, nothing to restamp, no
// clock of its own; the streams beside it keep their verdicts.
TEST(Diagnose, AResultWrittenAtOnceIsNotAStream) {
  test::TempDir dir;
  Faults f;
  f.trajectory_at_end = true;
  write_log(dir.file("result.lcm"), f, 1);
  auto d = diagnose(dir.file("result.lcm"));
  ASSERT_TRUE(d.ok()) << d.error().message;
  const auto& t = channel(*d, "TRAJECTORY");
  EXPECT_TRUE(t.written_at_once);
  EXPECT_EQ(t.verdict, "ok") << (t.reasons.empty() ? "" : t.reasons[0]);
  EXPECT_FALSE(t.clock_valid);
  EXPECT_FALSE(t.latency_valid);
  EXPECT_EQ(t.domain, -1);
  for (const auto& c : d->channels) {
    if (c.name != "TRAJECTORY") {
      EXPECT_EQ(c.verdict, "ok") << c.name << ": " << (c.reasons.empty() ? "" : c.reasons[0]);
    }
    EXPECT_EQ(c.written_at_once, c.name == "TRAJECTORY") << c.name;
  }
  for (const auto& dom : d->domains) {
    EXPECT_EQ(std::count(dom.channels.begin(), dom.channels.end(), "TRAJECTORY"), 0);
  }
  EXPECT_EQ(clock_corrections(*d).count("TRAJECTORY"), 0u);
}

TEST(Diagnose, CountsDropsDuplicatesAndReorderingExactly) {
  test::TempDir dir;
  Faults f;
  f.scan_drops = {17, 18, 19, 20, 21, 250, 400};  // a burst of 5 and two singles
  f.scan_duplicates = {100, 300};
  f.scan_reorder = 500;
  f.raw_gap = 10;
  write_log(dir.file("lossy.lcm"), f, 2);
  auto d = diagnose(dir.file("lossy.lcm"));
  ASSERT_TRUE(d.ok());
  const ChannelTiming& scan = channel(*d, "SCAN");
  EXPECT_EQ(scan.seq_gaps, 7);
  ASSERT_EQ(scan.gaps.size(), 3u);
  EXPECT_EQ(scan.gaps[0].missing, 5);
  EXPECT_EQ(scan.gaps[0].start_utime, kT0 + 1600000);
  EXPECT_EQ(scan.gaps[0].end_utime, kT0 + 2200000);
  EXPECT_EQ(scan.duplicates, 2);
  EXPECT_EQ(scan.out_of_order_stamp, 1);
  EXPECT_EQ(scan.verdict, "fault");
  const ChannelTiming& raw = channel(*d, "RAW");
  EXPECT_FALSE(raw.has_header);
  EXPECT_EQ(raw.missing_by_period, 10);
  EXPECT_EQ(raw.verdict, "warn");
  EXPECT_EQ(channel(*d, "IMU").verdict, "ok");
}

class DiagnoseSkew : public ::testing::TestWithParam<double> {};

TEST_P(DiagnoseSkew, RecoversARelativeOffsetWithin1ms) {
  test::TempDir dir;
  Faults f;
  f.imu_offset_s = GetParam();
  write_log(dir.file("skew.lcm"), f, 3);
  auto d = diagnose(dir.file("skew.lcm"));
  ASSERT_TRUE(d.ok());
  const StreamPair* p = pair(*d, "GROUND_TRUTH", "IMU");
  ASSERT_NE(p, nullptr);
  EXPECT_NEAR(p->offset_s, GetParam(), 0.001);
  EXPECT_GT(p->confidence, 0.9);
  const StreamPair* q = pair(*d, "IMU", "ODOM");
  ASSERT_NE(q, nullptr);
  EXPECT_NEAR(q->offset_s, -GetParam(), 0.001);
  ASSERT_FALSE(p->windows.empty());
  for (const auto& w : p->windows) EXPECT_NEAR(w.offset_s, GetParam(), 0.001);
  // The IMU's clock: ahead of its arrivals by the offset less the fastest delivery (0.3 ms).
  const ChannelTiming& imu = channel(*d, "IMU");
  ASSERT_TRUE(imu.clock_valid);
  EXPECT_NEAR(imu.clock_offset_s, GetParam() - 0.0003, 0.001);
  EXPECT_NEAR(imu.clock_drift_ppm, 0, 20);
}

INSTANTIATE_TEST_SUITE_P(Offsets, DiagnoseSkew, ::testing::Values(0.002, 0.015, 0.2));

class DiagnoseDrift : public ::testing::TestWithParam<double> {};

TEST_P(DiagnoseDrift, RecoversClockDriftWithin20ppm) {
  test::TempDir dir;
  Faults f;
  f.odom_drift_ppm = GetParam();
  write_log(dir.file("drift.lcm"), f, 4);
  auto d = diagnose(dir.file("drift.lcm"));
  ASSERT_TRUE(d.ok());
  const ChannelTiming& odom = channel(*d, "ODOM");
  ASSERT_TRUE(odom.clock_valid);
  EXPECT_NEAR(odom.clock_drift_ppm, GetParam(), 20);
  EXPECT_NE(odom.verdict, "ok");
  // The skew against ground truth grows along the log, as the windows show.
  const StreamPair* p = pair(*d, "GROUND_TRUTH", "ODOM");
  ASSERT_NE(p, nullptr);
  ASSERT_GE(p->windows.size(), 4u);
  const auto& first = p->windows.front();
  const auto& last = p->windows.back();
  const double expected_change = GetParam() * 1e-6 * (last.start_s - first.start_s);
  EXPECT_NEAR(last.offset_s - first.offset_s, expected_change, 0.1 * expected_change + 0.001);
}

INSTANTIATE_TEST_SUITE_P(Ppm, DiagnoseDrift, ::testing::Values(50.0, 300.0, 1000.0));

bool has_problem(const Diagnosis& d, const std::string& text) {
  for (const auto& p : d.tf.problems)
    if (p.find(text) != std::string::npos) return true;
  return false;
}

TEST(DiagnoseTf, FindsMissingFramesChangedStaticsFutureStampsLagAndStaleness) {
  test::TempDir dir;
  Faults f;
  f.laser_static_missing = true;
  f.static_changes = true;
  write_log(dir.file("a.lcm"), f, 6);
  auto a = diagnose(dir.file("a.lcm"));
  ASSERT_TRUE(a.ok());
  EXPECT_TRUE(has_problem(*a, "frame 'laser' of SCAN is not in the TF tree"));
  EXPECT_TRUE(has_problem(*a, "static transform 'base_link' -> 'imu' was republished with different values"));
  EXPECT_EQ(a->tf.problems.size(), 2u);

  Faults g;
  g.tf_delay_s = 0.12;  // transforms arrive 120 ms after their stamp: data waits too long for them
  g.tf_stops_at_s = 40;
  write_log(dir.file("b.lcm"), g, 7);
  auto b = diagnose(dir.file("b.lcm"));
  ASSERT_TRUE(b.ok());
  EXPECT_TRUE(has_problem(*b, "transform 'odom' -> 'base_link' (TF) is 12"));
  EXPECT_TRUE(has_problem(*b, "behind IMU, which it is composed with"));
  EXPECT_TRUE(has_problem(*b, "TF's stamps are 120.0 ms older than their arrival"));
  EXPECT_TRUE(has_problem(*b, "transform 'odom' -> 'base_link' goes stale"));

  Faults gap;  // in step with the data, but silent for a second in the middle
  gap.tf_stops_at_s = 30;
  write_log(dir.file("gap.lcm"), gap, 7);
  auto g2 = diagnose(dir.file("gap.lcm"));
  ASSERT_TRUE(g2.ok());
  EXPECT_TRUE(
      has_problem(*g2, "IMU messages find no transform 'odom' -> 'base_link' as new as their stamp within 70 ms"));

  Faults h;
  h.tf_future = true;
  write_log(dir.file("c.lcm"), h, 8);
  auto c = diagnose(dir.file("c.lcm"));
  ASSERT_TRUE(c.ok());
  // Stamped 20 ms ahead of measuring, delivered 1 ms after it: 19 ms ahead of arrival, every one.
  EXPECT_TRUE(has_problem(*c, "transform 'odom' -> 'base_link' (TF) is stamped 19.0 ms ahead of its arrival"))
      << nlohmann::json(c->tf.problems).dump();
}

const TfStampCheck* stamp_check(const Diagnosis& d, const std::string& channel, const std::string& child) {
  for (const auto& c : d.tf.stamps)
    if (c.channel == channel && c.child == child) return &c;
  return nullptr;
}

// The issue's `map -> odom` against `/odom`: a transform published slower than the data it is composed with is
// waited for up to its period, which is no problem (the check before this one called 40% of the IMU messages
// "extrapolation into the future" at 10 Hz); one stamped behind the data is, and by how much is measured.
TEST(DiagnoseTf, ATransformStampedBehindItsDataIsMeasuredOneAtALowerRateIsNot) {
  test::TempDir dir;
  Faults slow;
  slow.tf_period_s = 0.1;  // 10 Hz, stamped when published, arriving 1 ms later
  write_log(dir.file("slow.lcm"), slow, 3);
  auto a = diagnose(dir.file("slow.lcm"));
  ASSERT_TRUE(a.ok()) << a.error().message;
  EXPECT_TRUE(a->tf.problems.empty()) << a->tf.problems.front();
  const TfStampCheck* imu = stamp_check(*a, "IMU", "base_link");
  ASSERT_NE(imu, nullptr);
  EXPECT_EQ(imu->parent, "odom");
  EXPECT_EQ(imu->tf_channel, "TF");
  EXPECT_EQ(imu->frame, "imu");
  EXPECT_NEAR(imu->period_s, 0.1, 1e-6);
  // IMU messages stamped up to a period after the last transform; the first after one, an IMU period (5 ms) after
  // it: the lower envelope is that close to 0.
  EXPECT_GE(imu->offset_s, 0.0);
  EXPECT_LE(imu->offset_s, 0.0051);
  EXPECT_GT(imu->lead_s.max, 0.09);
  EXPECT_LT(imu->lead_s.max, 0.1);
  EXPECT_LT(imu->wait_s.max, 0.1);
  EXPECT_NEAR(imu->tf_latency_s, 0.001, 1e-6);

  Faults behind = slow;
  behind.tf_stamp_offset_s = -0.25;  // the localization's clock 250 ms behind
  write_log(dir.file("behind.lcm"), behind, 3);
  auto b = diagnose(dir.file("behind.lcm"));
  ASSERT_TRUE(b.ok()) << b.error().message;
  const TfStampCheck* late = stamp_check(*b, "IMU", "base_link");
  ASSERT_NE(late, nullptr);
  EXPECT_NEAR(late->offset_s - imu->offset_s, 0.25, 1e-6);  // moved by the clock's 250 ms, to the microsecond
  EXPECT_NEAR(late->lead_s.max - imu->lead_s.max, 0.25, 1e-6);
  EXPECT_NEAR(late->wait_s.p50, 0.30, 0.01);  // 250 ms and half a period
  EXPECT_NEAR(late->tf_latency_s, 0.251, 1e-6);
  EXPECT_TRUE(has_problem(*b, "transform 'odom' -> 'base_link' (TF) is 25"));
  EXPECT_TRUE(has_problem(*b, "ms behind IMU, which it is composed with, beyond its 100 ms period"));
  EXPECT_TRUE(has_problem(*b, "\"extrapolation into the future\""));
  EXPECT_TRUE(has_problem(*b, "the same for SCAN"));
  EXPECT_EQ(b->tf.problems.size(), 1u) << b->tf.problems.back();
}

TEST(DiagnoseTf, RosStaticChannelPublishedOnceIsStatic) {
  // ROS latches /tf_static: one message at the start. Were it taken as dynamic, it would go stale at once.
  EXPECT_TRUE(internal::is_static_tf_channel("/tf_static"));
  EXPECT_TRUE(internal::is_static_tf_channel("TF_STATIC"));
  EXPECT_FALSE(internal::is_static_tf_channel("/tf"));
  test::TempDir dir;
  Faults f;
  f.static_channel = "/tf_static";
  f.static_once = true;
  write_log(dir.file("ros.lcm"), f, 9);
  auto d = diagnose(dir.file("ros.lcm"));
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->tf.roots, (std::vector<std::string>{"world"}));
  EXPECT_TRUE(d->tf.problems.empty()) << d->tf.problems.front();
}

TEST(Diagnose, StreamsWithTheSameStampsAreNotPaired) {
  // POSE repeats the ground truth with its stamps: one clock stamped both, so there is no skew to measure
  // (a correlation would still find a peak at 0 and call it a measurement).
  test::TempDir dir;
  Faults f;
  f.copy_truth = true;
  f.imu_offset_s = 0.015;
  write_log(dir.file("copy.lcm"), f, 10);
  auto d = diagnose(dir.file("copy.lcm"));
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(pair(*d, "GROUND_TRUTH", "POSE"), nullptr);
  EXPECT_EQ(pair(*d, "POSE", "GROUND_TRUTH"), nullptr);
  // Each is still compared with the streams on other clocks (pairs are ordered by first appearance).
  const StreamPair* truth_imu = pair(*d, "GROUND_TRUTH", "IMU");
  const StreamPair* pose_imu = pair(*d, "POSE", "IMU");
  ASSERT_NE(truth_imu, nullptr);
  ASSERT_NE(pose_imu, nullptr);
  EXPECT_NEAR(truth_imu->offset_s, 0.015, 0.001);
  EXPECT_NEAR(pose_imu->offset_s, 0.015, 0.001);
}

bool has_reason(const ChannelTiming& c, const std::string& text) {
  for (const auto& r : c.reasons)
    if (r.find(text) != std::string::npos) return true;
  return false;
}

TEST(Diagnose, NamesStampsThatAreUnsetFrozenOrOnAnotherTimeBase) {
  // 20 s of 100 Hz IMU messages on eight channels, each arriving 0.5 ms after it was measured; only the stamps
  // differ. The thresholds: frozen when most repeat the stamp before (a 100 Hz source with a 1 ms clock never
  // repeats); a named time base when the offset is within 0.5 s of the named one (delivery is milliseconds).
  test::TempDir dir;
  {
    auto w = LogWriter::create(dir.file("stamps.lcm"));
    ASSERT_TRUE(w.ok());
    for (int64_t i = 0; i < 2000; ++i) {
      const int64_t measured = kT0 + i * 10000;
      const std::pair<const char*, int64_t> stamps[] = {
          {"GOOD", measured},
          {"FROZEN", kT0 + (i / 100) * 1000000},  // a new stamp once a second
          {"ZERO", 0},
          {"SIM", 120000000 + i * 10000},  // 120 s after a simulator started
          {"TAI", measured + 37000000},    // stamped in TAI, arrivals in UTC
          {"GPS", measured + 18000000},    // stamped in GPS time (a receiver's), arrivals in UTC
          // Every 40th message stamped 0.3, 0.6 or 0.9 s after it arrived (stamped after the fact): 50 of them.
          {"LATE", measured + (i % 40 == 0 ? 300000 * ((i / 40) % 3 + 1) : 0)},
          // Groups of three 1 ms apart every 30 ms: 100 Hz on average, nothing lost.
          {"BURST", kT0 + (i / 3) * 30000 + (i % 3) * 1000},
      };
      for (const auto& [name, stamp] : stamps) {
        driftlab::imu_t m{};
        m.header = {i, stamp, "imu"};
        const int64_t arrival = std::string_view(name) == "BURST" ? stamp + 500 : measured + 500;
        ASSERT_TRUE(w->write(arrival, name, encode(m)).ok());
      }
    }
    ASSERT_TRUE(w->close().ok());
  }
  auto d = diagnose(dir.file("stamps.lcm"));
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(channel(*d, "GOOD").verdict, "ok");
  EXPECT_EQ(channel(*d, "GOOD").repeated_stamps, 0);
  EXPECT_EQ(channel(*d, "FROZEN").repeated_stamps, 1980);
  EXPECT_TRUE(has_reason(channel(*d, "FROZEN"), "1980 of 2000 messages repeat the stamp"));
  EXPECT_EQ(channel(*d, "ZERO").zero_stamps, 2000);
  EXPECT_TRUE(has_reason(channel(*d, "ZERO"), "2000 messages are stamped 0"));
  // Each on a clock of its own, named by its offset and stamps, while most streams are on the recorder's.
  EXPECT_TRUE(has_reason(channel(*d, "SIM"), "stamps count from 130 s while the log's times are dates"));
  EXPECT_TRUE(has_reason(channel(*d, "SIM"), "stamped on another clock than its 4 peers"));
  // The median stamp is core/quantile.h's, numpy's np.median of the stamps: with 2000 of them, midway between the
  // 1000th and the 1001st (it was the 1001st alone, another median than every other one driftlab reports).
  EXPECT_EQ(channel(*d, "GOOD").median_stamp_utime, kT0 + 9'995'000);
  EXPECT_EQ(channel(*d, "SIM").median_stamp_utime, 129'995'000);
  EXPECT_TRUE(has_reason(channel(*d, "TAI"), "the 37 s between TAI and UTC"));
  EXPECT_TRUE(has_reason(channel(*d, "GPS"), "ahead of the log's times (the 18 s between GPS time and UTC)"));
  EXPECT_FALSE(has_reason(channel(*d, "GPS"), "TAI"));
  EXPECT_EQ(channel(*d, "GPS").verdict, "fault");
  // The late stamps are found and left out of the clock fit: the clock is the others' (0.5 ms behind arrival).
  const ChannelTiming& late = channel(*d, "LATE");
  EXPECT_EQ(late.late_stamps, 50);
  EXPECT_NEAR(late.late_stamp_max_s, 0.9, 1e-6);
  EXPECT_TRUE(has_reason(late, "50 stamps late by up to 0.900 s"));
  ASSERT_TRUE(late.clock_valid);
  EXPECT_NEAR(late.clock_offset_s, -0.0005, 1e-6);
  EXPECT_NEAR(late.clock_drift_ppm, 0, 1);
  const auto corrections = clock_corrections(*d);
  EXPECT_EQ(corrections.count("LATE"), 0u);
  EXPECT_EQ(corrections.count("GOOD"), 0u);
  ASSERT_EQ(corrections.count("TAI"), 1u);  // 37 s ahead: a clock ahead is corrected
  EXPECT_NEAR(corrections.at("TAI").offset_s, 36.9995, 1e-6);
  ASSERT_EQ(corrections.count("GPS"), 1u);
  EXPECT_NEAR(corrections.at("GPS").offset_s, 17.9995, 1e-6);
  // Bursts are burstiness, not drops.
  const ChannelTiming& burst = channel(*d, "BURST");
  EXPECT_TRUE(burst.bursty);
  EXPECT_NEAR(burst.expected_period_s, 0.01, 1e-4);
  EXPECT_EQ(burst.burst_size, 3);
  EXPECT_NEAR(burst.burst_interval_s, 0.001, 1e-9);
  EXPECT_EQ(burst.missing_by_period, 0);
  EXPECT_EQ(burst.seq_gaps, 0);
  EXPECT_TRUE(has_reason(burst, "bursts of about 3, 1.0 ms apart, 100.0"));
  EXPECT_FALSE(channel(*d, "GOOD").bursty);
}

/// What `driftlab replay --restamp auto` prints and puts in its JSON's notes: each correction applied with the
/// interval that made the diagnosis sure of it, each one left out with the interval that reaches zero; clocks
/// behind, steady or without a fit say nothing.
TEST(ClockCorrections, SayWhichTheyApplyAndWhichTheyLeaveOutAndWhy) {
  Diagnosis d;
  d.log = "run.lcm";
  d.start_utime = kT0;
  auto clock = [&](const char* name, double offset, std::array<double, 2> offset_ci, double drift,
                   std::array<double, 2> drift_ci, bool valid = true) {
    ChannelTiming c;
    c.name = name;
    c.clock_valid = valid;
    c.clock_offset_s = offset;
    c.clock_offset_ci_s = offset_ci;
    c.clock_drift_ppm = drift;
    c.clock_drift_ci_ppm = drift_ci;
    d.channels.push_back(c);
  };
  clock("AHEAD", 0.015, {0.0148, 0.0152}, 0.4, {-2, 2});         // sure: corrected
  clock("UNSURE", 0.002, {-0.001, 0.005}, 10, {-5, 25});         // ahead, but its interval reaches zero
  clock("DRIFTS", -0.004, {-0.0045, -0.0035}, 300, {280, 320});  // behind (left alone) and drifting (corrected)
  clock("WANDERS", 0.0, {-0.001, 0.001}, 40, {-10, 90});         // a drift its interval cannot tell from none
  clock("BEHIND", -0.004, {-0.0045, -0.0035}, 0, {-1, 1});       // latency, as far as one log can tell
  clock("NOFIT", 0.5, {0.4, 0.6}, 0, {0, 0}, false);
  std::vector<std::string> notes;
  const auto k = clock_corrections(d, &notes);
  ASSERT_EQ(k.size(), 2u);
  EXPECT_NEAR(k.at("AHEAD").offset_s, 0.015, 1e-12);
  EXPECT_EQ(k.at("AHEAD").drift_ppm, 0);  // the drift is not sure: not applied
  EXPECT_EQ(k.at("AHEAD").reference_utime, kT0);
  EXPECT_EQ(k.at("DRIFTS").offset_s, 0);
  EXPECT_NEAR(k.at("DRIFTS").drift_ppm, 300, 1e-12);
  const std::vector<std::string> expected = {
      "restamp AHEAD: +15.0 ms, +0 ppm (from the timing diagnosis of run.lcm: offset 95% +14.8 to +15.2 ms, drift -2 "
      "to +2 ppm)",
      "not restamping UNSURE: +2.0 ms (95%: -1.0 to +5.0), +10 ppm (95%: -5 to +25) could be zero",
      "restamp DRIFTS: +0.0 ms, +300 ppm (from the timing diagnosis of run.lcm: offset 95% -4.5 to -3.5 ms, drift "
      "+280 to +320 ppm)",
      "not restamping WANDERS: +0.0 ms (95%: -1.0 to +1.0), +40 ppm (95%: -10 to +90) could be zero",
  };
  EXPECT_EQ(notes, expected);
}

/// A log made with the fault model the simulator uses, its manifest written to the FAULTS channel; the
/// diagnosis is scored against that manifest, read back from the log.
/// `driftlab replay`'s corrections planned: the clocks from each log's diagnosis, merged with the first log's
/// correction of a channel kept; re-timing by hand needs no diagnosis (a log that cannot be read is not read); a
/// re-timing of neither form is an error naming it.
TEST(PlanCorrections, DiagnosesOnlyWhatItNeedsAndNamesABadRetiming) {
  test::TempDir dir;
  Faults f;
  f.odom_drift_ppm = 300;
  write_log(dir.file("drift.lcm"), f, 4);
  f.odom_drift_ppm = 1000;
  write_log(dir.file("more.lcm"), f, 5);
  auto d = diagnose(dir.file("drift.lcm"));
  ASSERT_TRUE(d.ok());
  std::vector<std::string> notes;
  const ClockCorrections expected = clock_corrections(*d, &notes);
  ASSERT_EQ(expected.count("ODOM"), 1u);  // 300 ppm is corrected, so the merge below has something to keep

  auto plan = plan_corrections({dir.file("drift.lcm"), dir.file("more.lcm")}, true, {});
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  EXPECT_NEAR(plan->clocks.at("ODOM").drift_ppm, expected.at("ODOM").drift_ppm, 1e-9);  // the first log's
  EXPECT_TRUE(plan->retime.empty());
  ASSERT_GT(plan->notes.size(), notes.size());  // the second log's notes follow the first's
  EXPECT_TRUE(std::equal(notes.begin(), notes.end(), plan->notes.begin()));

  auto by_hand = plan_corrections({"/nonexistent/x.lcm"}, false, {"ARM_CMD=0.12"});
  ASSERT_TRUE(by_hand.ok()) << by_hand.error().message;
  EXPECT_TRUE(by_hand->clocks.empty());
  EXPECT_EQ(by_hand->retime.at("ARM_CMD").us(), 120000);
  EXPECT_EQ(by_hand->notes,
            std::vector<std::string>{"retime ARM_CMD: each command starts 0.12 s before it arrived (--retime)"});

  for (const char* bad : {"ARM_CMD", "=0.1", "ARM_CMD=", "ARM_CMD=x", "ARM_CMD=0.1s", "ARM_CMD=-1", "ARM_CMD=4000"}) {
    auto p = plan_corrections({dir.file("drift.lcm")}, false, {bad});
    ASSERT_FALSE(p.ok()) << bad;
    EXPECT_EQ(p.error().message, std::string("--retime ") + bad + ": expected auto or CHANNEL=SECONDS (0..3600)");
  }
  auto unreadable = plan_corrections({"/nonexistent/x.lcm"}, false, {"auto"});
  ASSERT_FALSE(unreadable.ok());
  EXPECT_NE(unreadable.error().message.find("/nonexistent/x.lcm"), std::string::npos);
}

TEST(Diagnose, ScoredAgainstTheFaultManifest) {
  test::TempDir dir;
  const std::string path = dir.file("faulty.lcm");
  auto config = parse_faults(R"(seed: 11
streams:
  IMU: {clock_offset_s: 0.015, latency_s: 0.0003, jitter_s: 0.0002}
  ODOM: {clock_drift_ppm: 300, latency_s: 0.0008, jitter_s: 0.001}
  SCAN: {drop_probability: 0.03, burst_enter: 0.01, burst_exit: 0.3, duplicate_probability: 0.01, latency_s: 0.004}
)", "test");
  ASSERT_TRUE(config.ok()) << config.error().message;
  std::vector<Arrival> out;
  driftlab::fault_manifest_t manifest{};
  manifest.seed = static_cast<int64_t>(config->seed);
  auto stream = [&](const std::string& channel, double rate, auto make) {
    const StreamFaults f = config->streams.count(channel) ? config->streams.at(channel) : StreamFaults{};
    StreamFaultInjector inj(channel, f, config->seed, kT0);
    std::vector<Delivery> deliveries;
    for (int64_t seq = 0; seq / rate <= kSeconds; ++seq) {
      const double t = static_cast<double>(seq) / rate;
      const int64_t true_utime = kT0 + static_cast<int64_t>(std::llround(t * 1e6));
      deliveries.clear();
      inj.apply(seq, true_utime, deliveries);
      for (const Delivery& d : deliveries) out.push_back({d.arrival_utime, channel, make(seq, t, d.stamp_utime)});
    }
    for (auto& fault : inj.manifest(kT0 + static_cast<int64_t>(kSeconds * 1e6))) manifest.faults.push_back(fault);
  };
  stream("GROUND_TRUTH", 100, [](int64_t seq, double t, int64_t stamp) {
    driftlab::pose_t m{};
    m.header = {seq, stamp, "world"};
    m.orientation = {std::cos(yaw(t) / 2), 0, 0, std::sin(yaw(t) / 2)};
    return encode(m);
  });
  stream("IMU", 200, [](int64_t seq, double t, int64_t stamp) {
    driftlab::imu_t m{};
    m.header = {seq, stamp, "imu"};
    m.angular_velocity.z = yaw_rate(t);
    return encode(m);
  });
  stream("ODOM", 50, [](int64_t seq, double t, int64_t stamp) {
    driftlab::odometry_t m{};
    m.header = {seq, stamp, "odom"};
    m.angular_velocity.z = yaw_rate(t);
    return encode(m);
  });
  stream("SCAN", 10, [](int64_t seq, double, int64_t stamp) {
    driftlab::laser_scan_t m{};
    m.header = {seq, stamp, "laser"};
    return encode(m);
  });
  manifest.nfaults = static_cast<int32_t>(manifest.faults.size());
  manifest.header = {0, kT0, ""};
  out.push_back({kT0, "FAULTS", encode(manifest)});
  write_in_arrival_order(path, out);

  // The truth, from the log's manifest.
  driftlab::fault_manifest_t truth{};
  auto reader = LogReader::open(path, {.channels = "FAULTS"});
  ASSERT_TRUE(reader.ok());
  Event e;
  ASSERT_TRUE(reader->next(e));
  ASSERT_GT(truth.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
  std::set<int64_t> scan_lost;
  int64_t scan_duplicated = 0;
  double imu_offset = 0, odom_drift = 0;
  for (const auto& f : truth.faults) {
    if (f.channel == "SCAN" && (f.kind == "drop" || f.kind == "burst_drop")) scan_lost.insert(f.affected_seq.begin(), f.affected_seq.end());
    if (f.channel == "SCAN" && f.kind == "duplicate") scan_duplicated = f.naffected;
    if (f.channel == "IMU" && f.kind == "clock_offset") imu_offset = f.param_values[0];
    if (f.channel == "ODOM" && f.kind == "clock_drift") odom_drift = f.param_values[0];
  }
  ASSERT_GT(scan_lost.size(), 5u);
  ASSERT_GT(scan_duplicated, 0);

  auto d = diagnose(path);
  ASSERT_TRUE(d.ok());
  const ChannelTiming& scan = channel(*d, "SCAN");
  // Gaps are counted between the first and last message received.
  int64_t lo = 0, hi = static_cast<int64_t>(kSeconds * 10);
  while (scan_lost.count(lo)) ++lo;
  while (scan_lost.count(hi)) --hi;
  int64_t inside = 0;
  for (int64_t s : scan_lost) inside += s > lo && s < hi;
  EXPECT_EQ(scan.seq_gaps, inside);
  EXPECT_EQ(scan.duplicates, scan_duplicated);
  EXPECT_EQ(scan.verdict, "fault");
  const StreamPair* p = pair(*d, "GROUND_TRUTH", "IMU");
  ASSERT_NE(p, nullptr);
  EXPECT_NEAR(p->offset_s, imu_offset, 0.001);
  const ChannelTiming& odom = channel(*d, "ODOM");
  ASSERT_TRUE(odom.clock_valid);
  EXPECT_NEAR(odom.clock_drift_ppm, odom_drift, 20);
  EXPECT_EQ(channel(*d, "GROUND_TRUTH").verdict, "ok");
  for (const auto& c : d->channels) EXPECT_NE(c.name, "FAULTS");  // never read to diagnose
}

/// Range from the origin along angle a to the walls of the room [-4, 7] x [-3, 5] [m].
double room_range(double a) {
  const double c = std::cos(a), s = std::sin(a);
  double t = INFINITY;
  if (c > 1e-12) t = std::min(t, 7 / c);
  if (c < -1e-12) t = std::min(t, -4 / c);
  if (s > 1e-12) t = std::min(t, 5 / s);
  if (s < -1e-12) t = std::min(t, -3 / s);
  return t;
}

class DiagnoseScanSkew : public ::testing::TestWithParam<double> {};

/// A robot turning in place in a room, for a minute: its ground truth at 100 Hz and its 720-beam lidar at 10 Hz,
/// whose stamps are late by scan_late_s.
void write_room_log(const std::string& path, double scan_late_s) {
  std::vector<Arrival> out;
  for (int64_t i = 0; i * 0.01 <= kSeconds; ++i) {
    const double t = i * 0.01;
    driftlab::pose_t m{};
    m.header = {i, kT0 + static_cast<int64_t>(std::llround(t * 1e6)), "world"};
    m.orientation = {std::cos(yaw(t) / 2), 0, 0, std::sin(yaw(t) / 2)};
    out.push_back({m.header.utime + 100, "GROUND_TRUTH", encode(m)});
  }
  std::mt19937_64 rng(9);
  std::normal_distribution<double> noise(0, 0.01);
  for (int64_t i = 0; i * 0.1 <= kSeconds; ++i) {
    const double t = i * 0.1;
    driftlab::laser_scan_t m{};
    m.header = {i, kT0 + static_cast<int64_t>(std::llround((t + scan_late_s) * 1e6)), "laser"};
    m.nranges = 720;
    m.angle_min = static_cast<float>(-M_PI);
    m.angle_increment = static_cast<float>(2 * M_PI / 720);
    m.angle_max = m.angle_min + 719 * m.angle_increment;
    for (int b = 0; b < 720; ++b) {
      m.ranges.push_back(static_cast<float>(room_range(yaw(t) + m.angle_min + b * m.angle_increment) + noise(rng)));
    }
    out.push_back({kT0 + static_cast<int64_t>(std::llround((t + 0.004) * 1e6)), "SCAN", encode(m)});
  }
  write_in_arrival_order(path, out);
}

TEST_P(DiagnoseScanSkew, TellsTheScanClockFromTheRotationScansSee) {
  // A robot turning in place in a room; its lidar's stamps are late by the parameter.
  test::TempDir dir;
  const std::string path = dir.file("scan.lcm");
  write_room_log(path, GetParam());
  auto d = diagnose(path);
  ASSERT_TRUE(d.ok());
  const StreamPair* p = pair(*d, "GROUND_TRUTH", "SCAN");
  ASSERT_NE(p, nullptr);
  EXPECT_NEAR(p->offset_s, GetParam(), 0.001);
  EXPECT_GT(p->confidence, 0.9);
}

INSTANTIATE_TEST_SUITE_P(Offsets, DiagnoseScanSkew, ::testing::Values(0.0, 0.03));

TEST(Diagnose, ReadsOurHeaderInOtherProgramsTypes) {
  // A foreign type (its own fingerprint) that starts with driftlab.header_t: seq gaps are still found.
  test::TempDir dir;
  {
    auto w = LogWriter::create(dir.file("foreign.lcm"));
    ASSERT_TRUE(w.ok());
    for (int64_t seq = 0; seq < 200; ++seq) {
      if (seq == 50 || seq == 51) continue;
      driftlab::header_t h{seq, kT0 + seq * 10000, "sensor"};
      std::vector<uint8_t> data(8 + static_cast<size_t>(h._getEncodedSizeNoHash()) + 16, 0);
      data[0] = 0x12;  // a fingerprint no driftlab type has
      h._encodeNoHash(data.data(), 8, static_cast<int>(data.size()) - 8);
      ASSERT_TRUE(w->write(kT0 + seq * 10000 + 500, "FOREIGN", data).ok());
    }
    // An untyped channel whose bytes are not a header.
    for (int i = 0; i < 100; ++i) ASSERT_TRUE(w->write(kT0 + i * 20000, "BLOB", test::payload(i, 64)).ok());
    ASSERT_TRUE(w->close().ok());
  }
  auto d = diagnose(dir.file("foreign.lcm"));
  ASSERT_TRUE(d.ok());
  const ChannelTiming& foreign = channel(*d, "FOREIGN");
  EXPECT_TRUE(foreign.has_header);
  EXPECT_EQ(foreign.type, "");
  EXPECT_EQ(foreign.seq_gaps, 2);
  EXPECT_NEAR(foreign.latency_s.p50, 0.0005, 1e-9);
  EXPECT_FALSE(channel(*d, "BLOB").has_header);
}

/// The diagnosis of a log read in stretches, one per thread, is the one of a pass from the start, to the bit.
void expect_read_in_stretches_as_in_one_pass(const std::string& path, bool whole) {
  DiagnoseOptions one;
  one.pass_threads = 1;
  auto reference = diagnose(path, one);
  ASSERT_TRUE(reference.ok());
  EXPECT_EQ(reference->stretches, 1);
  const nlohmann::json expected = analyzers::to_json(*reference);
  for (int threads : {2, 3, 5, 16}) {
    DiagnoseOptions options;
    options.pass_threads = threads;
    auto d = diagnose(path, options);
    ASSERT_TRUE(d.ok());
    // Where the stretches cannot stand for one pass (a damaged log, a channel that changes at a join), it is read
    // again from the start.
    EXPECT_EQ(d->stretches, whole ? threads : 1) << path;
    EXPECT_EQ(analyzers::to_json(*d), expected) << path << " in " << threads << " stretches";
  }
}

TEST(Diagnose, ALogReadInStretchesOnThreadsIsDiagnosedAsInOnePass) {
  test::TempDir dir;
  // Every kind of sample a stretch keeps and joins: drops, duplicates, reordering, untyped messages (their
  // digests), transforms (given to the TF check in log order), poses (a yaw rate across each join), a result
  // written at once.
  Faults f;
  f.scan_drops = {5, 6, 300};
  f.scan_duplicates = {100, 400};
  f.scan_reorder = 250;
  f.raw_gap = 4;
  f.copy_truth = true;
  f.trajectory_at_end = true;
  f.imu_offset_s = 0.01;
  write_log(dir.file("faults.lcm"), f, 3);
  expect_read_in_stretches_as_in_one_pass(dir.file("faults.lcm"), true);
  // Scans: the rotation between the last scan before a join and the first after it.
  write_room_log(dir.file("room.lcm"), 0.03);
  expect_read_in_stretches_as_in_one_pass(dir.file("room.lcm"), true);

  // A foreign type that carries our header until its messages become too short for one: one pass calls the
  // channel untyped from there on, and keeps the digests of its messages from there. A stretch that begins after
  // that point begins without a header and joins; one that loses it inside joins too. A stretch that begins
  // with a header after one that lost it (the messages were short only for a while) cannot: one pass reads it.
  struct Loss {
    double from, to;  // the fraction of the messages that are short
    bool whole;       // read in stretches
  };
  for (const Loss loss : {Loss{0.3, 1, true}, Loss{0.97, 1, true}, Loss{0.3, 0.35, false}}) {
    const std::string path = dir.file("foreign" + std::to_string(loss.from) + std::to_string(loss.to) + ".lcm");
    std::vector<Arrival> out;
    constexpr int64_t kMessages = 3000;
    for (int64_t seq = 0; seq < kMessages; ++seq) {
      driftlab::header_t h{seq, kT0 + seq * 20000, "sensor"};
      std::vector<uint8_t> data(8 + static_cast<size_t>(h._getEncodedSizeNoHash()) + 16, 0);
      data[0] = 0x12;  // a fingerprint no driftlab type has
      h._encodeNoHash(data.data(), 8, static_cast<int>(data.size()) - 8);
      const double at = static_cast<double>(seq) / kMessages;
      if (at >= loss.from && at < loss.to) data.resize(6);
      out.push_back({kT0 + seq * 20000 + 500, "FOREIGN", data});
      out.push_back({kT0 + seq * 20000 + 700, "BLOB", test::payload(static_cast<uint64_t>(seq), 300)});
    }
    write_in_arrival_order(path, out);
    expect_read_in_stretches_as_in_one_pass(path, loss.whole);
  }

  // A damaged log: its problems are found and told by one pass.
  {
    std::vector<uint8_t> bytes = test::read_file(dir.file("faults.lcm"));
    for (size_t i = bytes.size() / 2; i < bytes.size() / 2 + 300; ++i) bytes[i] = 0x5a;
    test::write_file(dir.file("damaged.lcm"), bytes);
  }
  expect_read_in_stretches_as_in_one_pass(dir.file("damaged.lcm"), false);
  DiagnoseOptions options;
  options.pass_threads = 4;
  auto d = diagnose(dir.file("damaged.lcm"), options);
  ASSERT_TRUE(d.ok());
  EXPECT_GT(d->log_problems, 0u);
}

TEST(Diagnose, MissingFileIsAnErrorNamingIt) {
  auto d = diagnose("/nonexistent/x.lcm");
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("/nonexistent/x.lcm"), std::string::npos);
}

// What `driftlab diagnose --json` and `driftlab diagnose` print (the command prints these two and nothing else).
TEST(DiagnoseRun, GivesTheJsonTheIssueAsksForAndTheLines) {
  test::TempDir dir;
  Faults f;
  f.scan_drops = {5};
  write_log(dir.file("x.lcm"), f, 5);
  auto run = run_diagnosis(dir.file("x.lcm"), {});
  ASSERT_TRUE(run) << run.error().message;
  const auto j = nlohmann::json::parse(diagnose_json(*run).dump());
  for (const char* key : {"log", "channels", "pairs", "tf"}) EXPECT_TRUE(j.contains(key)) << key;
  const auto& c = j["channels"][0];
  for (const char* key : {"name", "type", "count", "rate_hz", "expected_period_s", "drops", "duplicates",
                          "out_of_order", "latency_s", "clock", "verdict", "reasons"}) {
    EXPECT_TRUE(c.contains(key)) << key;
  }
  bool found = false;
  for (const auto& ch : j["channels"]) {
    if (ch["name"] == "SCAN") {
      found = true;
      EXPECT_EQ(ch["drops"]["seq_gaps"], 1);
      EXPECT_EQ(ch["verdict"], "fault");
    }
  }
  EXPECT_TRUE(found);
  const std::string table = to_text(diagnosis_text(*run));
  EXPECT_NE(table.find("SCAN: 1 messages missing"), std::string::npos) << table;
}

}  // namespace
}  // namespace driftlab::analyzers
