// The timing diagnosis on recordings users bring (issue 26): Gazebo runs recorded with use_sim_time, where every
// stamp is simulation time and every arrival a wall-clock date; ROS 2 headers without sequence numbers; /tf
// carrying several broadcasters' transforms. The bags are written by the writers Foxglove runs
// (tests/oracle/write_mcap.mjs: @mcap/core and @foxglove/rosmsg2-serialization), with faults whose size the test
// knows, and read as a user does: `driftlab import`, then the diagnosis. The real Nav2 bag
// (../shared/data/bags/nav2_turtlebot.mcap) is held to what a person finds by looking at it.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "analyzers/arm_tracking.h"
#include "analyzers/log_info.h"
#include "analyzers/timing.h"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "formats/import.h"
#include "tests/formats/oracle.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using analyzers::ChannelTiming;
using analyzers::Diagnosis;

/// A Gazebo-style run: simulation time from 0 at a real-time factor that wanders (0.95 to 0.99 over 40 s), the
/// bag's times on the wall clock from 2026-05-28.
struct SimRun {
  double duration_s = 60;
  int64_t wall0_us = 1'780'000'000'000'000;
  static double rtf(double sim_s) { return 0.97 + 0.02 * std::sin(2 * M_PI * sim_s / 40); }
  std::vector<double> wall_at_ms;  // wall-clock seconds since wall0 at each millisecond of simulation time
  SimRun() {
    wall_at_ms.resize(static_cast<size_t>(duration_s * 1000) + 2);
    for (size_t i = 1; i < wall_at_ms.size(); ++i) wall_at_ms[i] = wall_at_ms[i - 1] + 1e-3 / rtf((i - 0.5) * 1e-3);
  }
  /// The wall-clock time [us] when simulation time reached sim_s.
  int64_t wall_us(double sim_s) const {
    const double x = std::clamp(sim_s * 1000, 0.0, static_cast<double>(wall_at_ms.size() - 2));
    const auto i = static_cast<size_t>(x);
    const double w = wall_at_ms[i] + (x - static_cast<double>(i)) * (wall_at_ms[i + 1] - wall_at_ms[i]);
    return wall0_us + std::llround(w * 1e6);
  }
};

/// Deterministic delivery jitter in [0, 1) ms.
double jitter_ms(uint64_t i) { return static_cast<double>((i * 2654435761u) % 1000) * 1e-3; }

nlohmann::json ros_time(int64_t us) { return {{"sec", us / 1'000'000}, {"nanosec", (us % 1'000'000) * 1000}}; }
nlohmann::json header(int64_t us, const std::string& frame) { return {{"stamp", ros_time(us)}, {"frame_id", frame}}; }
nlohmann::json vec3(double x = 0, double y = 0, double z = 0) { return {{"x", x}, {"y", y}, {"z", z}}; }
nlohmann::json quat() { return {{"x", 0}, {"y", 0}, {"z", 0}, {"w", 1}}; }
nlohmann::json transform(int64_t us, const std::string& parent, const std::string& child, double x) {
  return {{"header", header(us, parent)},
          {"child_frame_id", child},
          {"transform", {{"translation", vec3(x)}, {"rotation", quat()}}}};
}

struct Faults {
  double scan_late_ms = 37;  // /scan delivered this much after the others
  std::vector<std::pair<double, double>> odom_holes = {{20.0, 1.0}, {40.0, 0.3}};  // (start, length) [s of sim]
  double map_odom_ahead_s = 0.5;   // map -> odom post-dated, as AMCL does
  bool imu_on_wall_clock = false;  // the IMU's node without use_sim_time
  double clock_hz = 0;             // the simulator's /clock, published at this rate (0: not recorded)
  double bridge_late_ms = 0;       // every sensor stream delivered this much late (a bridge), /clock on time
};

/// The bag's messages (as write_mcap.mjs takes them), in arrival order; out: the holes' message counts.
nlohmann::json sim_bag(const SimRun& run, const Faults& f, int64_t* odom_missing) {
  std::vector<nlohmann::json> msgs;
  auto add = [&](const std::string& topic, const std::string& type, int64_t arrival_us, nlohmann::json msg) {
    msgs.push_back({{"topic", topic}, {"type", type}, {"time_ns", arrival_us * 1000}, {"sequence", 0}, {"msg", msg}});
  };
  uint64_t n = 0;
  const int64_t steps = static_cast<int64_t>(run.duration_s * 1000);
  *odom_missing = 0;
  for (int64_t ms = 1; ms < steps; ++ms) {  // stamps on whole milliseconds of simulation time
    const double t = static_cast<double>(ms) * 1e-3;
    const int64_t stamp = ms * 1000;
    auto arrive = [&](double extra_ms) {
      return run.wall_us(t) + std::llround((f.bridge_late_ms + extra_ms + jitter_ms(++n)) * 1e3);
    };
    if (f.clock_hz > 0 && ms % std::llround(1000 / f.clock_hz) == 0) {  // the simulator's clock, 0.1 ms transport
      add("/clock", "rosgraph_msgs/msg/Clock", run.wall_us(t) + std::llround((0.1 + 0.2 * jitter_ms(++n)) * 1e3),
          {{"clock", ros_time(stamp)}});
    }
    if (ms % 10 == 0) {  // IMU at 100 Hz, 0.2 ms transport
      const int64_t at = arrive(0.2);
      const int64_t imu_stamp = f.imu_on_wall_clock ? run.wall_us(t) : stamp;
      add("/imu", "sensor_msgs/msg/Imu", at,
          {{"header", header(imu_stamp, "imu_link")},
           {"orientation", quat()},
           {"orientation_covariance", std::vector<double>(9, 0.0)},
           {"angular_velocity", vec3(0, 0, 0.1)},
           {"angular_velocity_covariance", std::vector<double>(9, 0.0)},
           {"linear_acceleration", vec3(0, 0, 9.81)},
           {"linear_acceleration_covariance", std::vector<double>(9, 0.0)}});
    }
    if (ms % 20 == 0) {  // odometry and its transform at 50 Hz, with holes
      bool in_hole = false;
      for (const auto& [start, length] : f.odom_holes) in_hole = in_hole || (t >= start && t < start + length - 1e-9);
      if (in_hole) {
        ++*odom_missing;
      } else {
        add("/odom", "nav_msgs/msg/Odometry", arrive(0.5),
            {{"header", header(stamp, "odom")},
             {"child_frame_id", "base_link"},
             {"pose",
              {{"pose", {{"position", vec3(t)}, {"orientation", quat()}}},
               {"covariance", std::vector<double>(36, 0.0)}}},
             {"twist",
              {{"twist", {{"linear", vec3(1)}, {"angular", vec3()}}}, {"covariance", std::vector<double>(36, 0.0)}}}});
      }
      add("/tf", "tf2_msgs/msg/TFMessage", arrive(0.6), {{"transforms", {transform(stamp, "odom", "base_link", t)}}});
    }
    if (ms % 100 == 0) {  // the scan at 10 Hz, late
      add("/scan", "sensor_msgs/msg/LaserScan", arrive(f.scan_late_ms),
          {{"header", header(stamp, "laser")},
           {"angle_min", -1.5},
           {"angle_max", 1.5},
           {"angle_increment", 0.5},
           {"time_increment", 0.0},
           {"scan_time", 0.1},
           {"range_min", 0.1},
           {"range_max", 10.0},
           {"ranges", std::vector<double>(7, 2.0)},
           {"intensities", std::vector<double>()}});
    }
    if (ms % 200 == 0) {  // the localizer's map -> odom at 5 Hz, post-dated, 20 ms of processing
      add("/tf", "tf2_msgs/msg/TFMessage", arrive(20),
          {{"transforms", {transform(stamp + std::llround(f.map_odom_ahead_s * 1e6), "map", "odom", 0.0)}}});
    }
  }
  // The robot's static transforms, stamped 0 as static broadcasters may.
  add("/tf_static", "tf2_msgs/msg/TFMessage", run.wall_us(0) + 100,
      {{"transforms", {transform(0, "base_link", "laser", 0.2), transform(0, "base_link", "imu_link", 0.0)}}});
  std::stable_sort(msgs.begin(), msgs.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
    return a["time_ns"].get<int64_t>() < b["time_ns"].get<int64_t>();
  });
  return {{"profile", "ros2"}, {"compression", "zstd"}, {"messages", msgs}};
}

/// The bag written by Foxglove's writers, imported and diagnosed; false when node is missing (skipped).
bool diagnose_bag(const nlohmann::json& spec, const test::TempDir& dir, Diagnosis* out) {
  const std::string bag = dir.file("run.mcap"), log = dir.file("run.lcm");
  if (!test::oracle_write_mcap(spec, bag)) return false;
  auto imported = formats::import_log(bag, log, [](const std::string& p) { ADD_FAILURE() << p; });
  EXPECT_TRUE(imported.ok()) << imported.error().message;
  auto d = analyzers::diagnose(log);
  EXPECT_TRUE(d.ok()) << d.error().message;
  if (!d.ok()) return false;
  *out = std::move(*d);
  return true;
}

const ChannelTiming& channel(const Diagnosis& d, const std::string& name) {
  for (const auto& c : d.channels) {
    if (c.name == name) return c;
  }
  ADD_FAILURE() << "no channel " << name;
  static const ChannelTiming none;
  return none;
}

bool has_reason(const ChannelTiming& c, const std::string& words) {
  return std::any_of(c.reasons.begin(), c.reasons.end(),
                     [&](const std::string& r) { return r.find(words) != std::string::npos; });
}

std::string reasons(const ChannelTiming& c) { return nlohmann::json(c.reasons).dump(); }

// A Gazebo run with use_sim_time: one clock (simulation time) for every stream, its real-time factor measured once,
// each stream's latency against its peers in milliseconds; the late scan named late by the injected 37 ms; the
// odometry's holes found from its period (ROS 2 sends no sequence number); /tf's two broadcasters not taken for
// reordering, and the localizer's post-dated map -> odom named as the TF finding; /tf_static stamped 0 not a fault.
TEST(DiagnoseSimTimeBag, OneClockTheLateStreamTheHolesAndTheTree) {
  const SimRun run;
  const Faults faults;
  int64_t odom_missing = 0;
  const auto spec = sim_bag(run, faults, &odom_missing);
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(spec, dir, &d)) return;

  ASSERT_EQ(d.domains.size(), 1u) << nlohmann::json(d.domains.size()).dump();
  const auto& sim = d.domains[0];
  EXPECT_EQ(sim.kind, "simulation") << sim.description;
  EXPECT_EQ(sim.channels, (std::vector<std::string>{"/imu", "/odom", "/scan", "/tf"}));
  // The real-time factor over the run: simulated seconds over wall-clock seconds, from the run itself. The
  // reference is the fastest delivery (0.2 ms, jitter under 1 ms) at both ends of a 61 s run: 2e-5 of error.
  const double rtf = run.duration_s / (static_cast<double>(run.wall_us(run.duration_s) - run.wall0_us) * 1e-6);
  ASSERT_TRUE(sim.rate_valid);
  EXPECT_NEAR(sim.rate, rtf, 1e-3);
  // Over 10 s windows it wanders with the run's (0.95 to 0.99).
  EXPECT_LT(sim.rate_min, 0.96);
  EXPECT_GT(sim.rate_max, 0.98);

  for (const auto& c : d.channels) {
    SCOPED_TRACE(c.name);
    if (c.has_header) {
      EXPECT_LT(std::abs(c.latency_s.p50), 0.1);  // never 10^12 ms
    }
    EXPECT_FALSE(has_reason(c, "drifts")) << reasons(c);          // the real-time factor is the clock's, once
  }
  // The late stream, by the injected amount: it and its peers each have up to 1 ms of jitter above their
  // transports (0.2 to 0.6 ms), and the fastest deliveries are compared, so within 3 ms.
  const auto& scan = channel(d, "/scan");
  EXPECT_NEAR(scan.peer_delay_s * 1e3, faults.scan_late_ms, 3.0);
  EXPECT_TRUE(has_reason(scan, "arrives")) << reasons(scan);
  EXPECT_EQ(scan.verdict, "warn") << reasons(scan);
  for (const char* prompt : {"/imu", "/odom"}) {
    SCOPED_TRACE(prompt);
    EXPECT_LT(std::abs(channel(d, prompt).peer_delay_s), 0.003);
  }
  EXPECT_EQ(channel(d, "/imu").verdict, "ok") << reasons(channel(d, "/imu"));

  // The holes: no sequence number travelled, so they come from the 20 ms period, each with its place.
  const auto& odom = channel(d, "/odom");
  EXPECT_TRUE(odom.seq_counted);
  EXPECT_NEAR(static_cast<double>(odom.missing_by_period), static_cast<double>(odom_missing), 1.0);
  ASSERT_EQ(odom.gaps.size(), faults.odom_holes.size());
  for (size_t i = 0; i < odom.gaps.size(); ++i) {
    const auto& [start, length] = faults.odom_holes[i];
    // The gap runs from the last message before the hole (one period earlier) to the first after it, on the
    // recorder's clock: the hole's wall-clock span plus one period, to the jitter.
    const double expect_start_s = static_cast<double>(run.wall_us(start - 0.02) - run.wall0_us) * 1e-6;
    const double expect_len_s = static_cast<double>(run.wall_us(start + length) - run.wall_us(start - 0.02)) * 1e-6;
    EXPECT_NEAR(static_cast<double>(odom.gaps[i].start_utime - d.start_utime) * 1e-6, expect_start_s, 0.005);
    EXPECT_NEAR(static_cast<double>(odom.gaps[i].end_utime - odom.gaps[i].start_utime) * 1e-6, expect_len_s, 0.005);
  }
  EXPECT_TRUE(has_reason(odom, "hole")) << reasons(odom);

  // /tf: odometry's and the localizer's transforms interleave; neither steps back.
  const auto& tf = channel(d, "/tf");
  EXPECT_EQ(tf.out_of_order_stamp, 0);
  EXPECT_FALSE(has_reason(tf, "reordered")) << reasons(tf);
  const auto edge =
      std::find_if(d.tf.edges.begin(), d.tf.edges.end(), [](const analyzers::TfEdge& e) { return e.child == "odom"; });
  ASSERT_NE(edge, d.tf.edges.end());
  EXPECT_EQ(edge->parent, "map");
  EXPECT_NEAR(edge->rate_hz, 5.0, 0.01);
  EXPECT_EQ(edge->ahead, edge->count);
  // Post-dated by 500 ms of simulation time (a little more of the wall clock's, at the run's real-time factor) and
  // delivered 20 ms (+ jitter) after the fastest stream: each transform's age is its arrival minus the wall-clock
  // time its stamp stands for; the median of those, within the fastest stream's transport and jitter.
  std::vector<double> ages;
  for (const auto& m : spec["messages"]) {
    if (m["topic"] != "/tf" || m["msg"]["transforms"][0]["child_frame_id"] != "odom") continue;
    const auto& stamp = m["msg"]["transforms"][0]["header"]["stamp"];
    const double sim_s = stamp["sec"].get<double>() + stamp["nanosec"].get<double>() * 1e-9;
    ages.push_back(m["time_ns"].get<double>() * 1e-9 - static_cast<double>(run.wall_us(sim_s)) * 1e-6);
  }
  std::nth_element(ages.begin(), ages.begin() + static_cast<std::ptrdiff_t>(ages.size() / 2), ages.end());
  EXPECT_NEAR(edge->age_s.p50, ages[ages.size() / 2], 0.002);
  const bool named = std::any_of(d.tf.problems.begin(), d.tf.problems.end(), [](const std::string& p) {
    return p.find("'map' -> 'odom'") != std::string::npos && p.find("ahead of its arrival") != std::string::npos;
  });
  EXPECT_TRUE(named) << nlohmann::json(d.tf.problems).dump();
  EXPECT_NE(channel(d, "/tf_static").verdict, "fault") << reasons(channel(d, "/tf_static"));
}

// The simulator's /clock recorded with the streams (rosgraph_msgs/Clock, as Gazebo publishes it): the reference of
// the simulation's clock, so latency has an absolute zero. A bridge delivers every sensor stream 25 ms late: against
// the fastest peer that is invisible, against /clock each stream is named late by its own delay (the scan by its
// 37 ms more), within 3 ms: the streams' jitter is under 1 ms above their 0.2-0.6 ms transports, /clock's 0.2 ms.
TEST(DiagnoseSimTimeBag, TheSimulatorsClockIsTheReferenceWhereItWasRecorded) {
  const SimRun run;
  Faults faults;
  faults.clock_hz = 100;
  faults.bridge_late_ms = 25;
  int64_t odom_missing = 0;
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(sim_bag(run, faults, &odom_missing), dir, &d)) return;
  ASSERT_EQ(d.domains.size(), 1u);
  const auto& sim = d.domains[0];
  EXPECT_EQ(sim.kind, "simulation") << sim.description;
  EXPECT_EQ(sim.reference, "/clock");
  EXPECT_EQ(sim.channels, (std::vector<std::string>{"/clock", "/imu", "/odom", "/scan", "/tf"}));
  const double rtf = run.duration_s / (static_cast<double>(run.wall_us(run.duration_s) - run.wall0_us) * 1e-6);
  ASSERT_TRUE(sim.rate_valid);
  EXPECT_NEAR(sim.rate, rtf, 1e-3);
  const auto& clock = channel(d, "/clock");
  EXPECT_EQ(clock.source_type, "rosgraph_msgs/msg/Clock");
  EXPECT_TRUE(clock.has_header);
  EXPECT_NEAR(clock.rate_hz, 100 * rtf, 1.0);
  EXPECT_EQ(clock.verdict, "ok") << reasons(clock);
  EXPECT_NEAR(clock.peer_delay_s * 1e3, 0, 0.5);
  for (const auto& [name, late_ms] :
       std::vector<std::pair<std::string, double>>{{"/imu", faults.bridge_late_ms},
                                                   {"/odom", faults.bridge_late_ms},
                                                   {"/scan", faults.bridge_late_ms + faults.scan_late_ms}}) {
    SCOPED_TRACE(name);
    const auto& c = channel(d, name);
    EXPECT_NEAR(c.peer_delay_s * 1e3, late_ms, 3.0);
    EXPECT_NEAR(c.latency_s.p50 * 1e3, late_ms, 3.0);
    EXPECT_TRUE(has_reason(c, "after the simulator's clock (/clock")) << reasons(c);
  }
}

// A simulator's /clock in a recording whose streams are on the wall clock (no node has use_sim_time): /clock is
// simulation time by definition, never "on another clock than its peers"; the streams are judged as stamped.
TEST(DiagnoseSimTimeBag, ClockIsNeverTheWrongTimeBase) {
  const SimRun run;
  Faults faults;
  faults.clock_hz = 50;
  int64_t odom_missing = 0;
  nlohmann::json spec = sim_bag(run, faults, &odom_missing);
  for (auto& m : spec["messages"]) {  // every stream restamped with its wall-clock time, /clock left as it is
    if (m["topic"] == "/clock") continue;
    nlohmann::json& h = m["msg"].contains("transforms") ? m["msg"]["transforms"][0] : m["msg"];
    if (h["header"]["stamp"]["sec"] == 0) continue;  // static transforms
    const auto& st = h["header"]["stamp"];
    const double sim_s = st["sec"].get<double>() + st["nanosec"].get<double>() * 1e-9;
    h["header"] = header(run.wall_us(sim_s), h["header"]["frame_id"]);
  }
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(spec, dir, &d)) return;
  EXPECT_FALSE(has_reason(channel(d, "/clock"), "another clock")) << reasons(channel(d, "/clock"));
  for (const char* name : {"/imu", "/odom", "/scan"}) {
    SCOPED_TRACE(name);
    EXPECT_FALSE(has_reason(channel(d, name), "another clock")) << reasons(channel(d, name));
    EXPECT_LT(std::abs(channel(d, name).latency_s.p50), 0.05);
  }
}

// The field report's IMU: its node stamps with the wall clock while everything else runs on simulation time. The
// IMU, and only it, is on the wrong time base.
TEST(DiagnoseSimTimeBag, AStreamOnTheWallClockAmongSimulationTimeIsTheWrongTimeBase) {
  const SimRun run;
  Faults faults;
  faults.imu_on_wall_clock = true;
  int64_t odom_missing = 0;
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(sim_bag(run, faults, &odom_missing), dir, &d)) return;
  ASSERT_EQ(d.domains.size(), 2u);
  const auto& imu = channel(d, "/imu");
  EXPECT_EQ(imu.verdict, "fault");
  EXPECT_TRUE(has_reason(imu, "stamped on another clock than its 3 peers")) << reasons(imu);
  EXPECT_TRUE(has_reason(imu, "use_sim_time not set")) << reasons(imu);
  for (const char* other : {"/odom", "/scan", "/tf"}) {
    SCOPED_TRACE(other);
    EXPECT_FALSE(has_reason(channel(d, other), "stamped on another clock")) << reasons(channel(d, other));
  }
}

// The Nav2 TurtleBot bag (../shared/data/bags/nav2_turtlebot.mcap, from evo's test data): a simulated robot whose
// nodes stamp with simulation time (924-1,040 s) while the bag's times are dates in 2026. What a person finds by
// looking at it: the stamps advance 0.993 s per second of the bag (the simulation's real-time factor); /odom
// (30 Hz) has one hole of 2.16 s 41 s into the bag; AMCL stamps map -> odom about a second ahead of its arrival
// (its transform_tolerance); odom -> base_footprint comes from the odometry's broadcaster.
TEST(DiagnoseNav2Bag, OneSimulationClockTheOdometryHoleAndAmclsPostDatedTransform) {
  const std::string bag = test::shared_data("bags/nav2_turtlebot.mcap");
  if (bag.empty()) return;
  test::TempDir dir;
  auto imported = formats::import_log(bag, dir.file("nav2.lcm"), [](const std::string& p) { ADD_FAILURE() << p; });
  ASSERT_TRUE(imported.ok()) << imported.error().message;
  auto result = analyzers::diagnose(dir.file("nav2.lcm"));
  ASSERT_TRUE(result.ok()) << result.error().message;
  const Diagnosis& d = *result;
  ASSERT_EQ(d.domains.size(), 1u);
  EXPECT_EQ(d.domains[0].kind, "simulation") << d.domains[0].description;
  ASSERT_TRUE(d.domains[0].rate_valid);
  EXPECT_NEAR(d.domains[0].rate, 0.9932, 0.001);
  for (const auto& c : d.channels) {
    SCOPED_TRACE(c.name);
    if (c.has_header) {
      EXPECT_LT(std::abs(c.latency_s.p50), 1.0);
    }
    EXPECT_FALSE(has_reason(c, "reordered")) << reasons(c);
    EXPECT_FALSE(has_reason(c, "drifts")) << reasons(c);
  }
  EXPECT_NE(channel(d, "/tf_static").verdict, "fault") << reasons(channel(d, "/tf_static"));
  const auto& odom = channel(d, "/odom");
  ASSERT_FALSE(odom.gaps.empty()) << reasons(odom);
  const auto longest = *std::max_element(odom.gaps.begin(), odom.gaps.end(), [](const auto& a, const auto& b) {
    return a.end_arrival - a.start_arrival < b.end_arrival - b.start_arrival;
  });
  // The bag goes 2.16 s without odometry from 41.1 s; its stamps show 1.76 s missing (48 messages of its 36 ms
  // period): the messages after the hole came late, and caught up.
  EXPECT_NEAR(static_cast<double>(longest.end_arrival - longest.start_arrival) * 1e-6, 2.16, 0.01);
  EXPECT_NEAR(static_cast<double>(longest.start_arrival - d.start_utime) * 1e-6, 41.1, 0.1);
  EXPECT_NEAR(static_cast<double>(odom.missing_by_period), 48, 1);
  EXPECT_TRUE(has_reason(odom, "hole")) << reasons(odom);
  const bool amcl = std::any_of(d.tf.problems.begin(), d.tf.problems.end(), [](const std::string& p) {
    return p.find("'map' -> 'odom'") != std::string::npos && p.find("ahead of its arrival") != std::string::npos;
  });
  EXPECT_TRUE(amcl) << nlohmann::json(d.tf.problems).dump();
}

/// The worst stream as the headline names it (diagnose's problems, the report's summary): the highest problem_rank.
const ChannelTiming* worst_stream(const Diagnosis& d) {
  const ChannelTiming* worst = nullptr;
  auto rank = [](const ChannelTiming& c) {
    return analyzers::problem_rank(c.verdict, c.causes.empty() ? analyzers::Cause::kSymptom : c.causes[0],
                                   c.reasons.size());
  };
  for (const auto& c : d.channels) {
    if (rank(c) > 0 && (worst == nullptr || rank(c) > rank(*worst))) worst = &c;
  }
  return worst;
}

/// A MoveIt-style arm on ros2_control, recorded on the wall clock: MoveIt hands the controller a plan of 2 s every
/// 2 s (points every 100 ms, positions and velocities), and the joints, published by the joint state broadcaster at
/// 100 Hz, follow the plan `delay_ms` later. ROS 2 writes the trajectory on its topic, ROS 1 sends it as
/// FollowJointTrajectory action goals (how MoveIt's ROS 1 controller manager hands it over); the trajectory
/// stamped 0, as MoveIt leaves it, so the controller starts it when it arrives. Some joint states arrive in a
/// burst, out of order (a symptom on another stream the headline must not put first).
/// With a controller state (control_msgs/JointTrajectoryControllerState, in the layout of a `controller` release),
/// the controller publishes it at 100 Hz: its reference the plan `delay_ms - tracking_lag_ms` late (its plans start
/// late), its feedback the joints, its output the velocities of the plan.
enum class Controller { kNone, kBeforeHumble, kHumble, kJazzy };
nlohmann::json arm_bag(bool ros2, double delay_ms, double duration_s, Controller controller = Controller::kNone,
                       double tracking_lag_ms = 0) {
  const std::vector<std::string> joints = {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint"};
  auto q = [](size_t j, double t) { return 0.6 * std::sin(2 * M_PI * (0.3 + 0.1 * j) * t + j); };
  auto qd = [](size_t j, double t) {
    return 0.6 * 2 * M_PI * (0.3 + 0.1 * j) * std::cos(2 * M_PI * (0.3 + 0.1 * j) * t + j);
  };
  const int64_t wall0 = 1'780'000'000'000'000;
  auto time_msg = [&](int64_t us) {
    return ros2 ? nlohmann::json{{"sec", us / 1'000'000}, {"nanosec", (us % 1'000'000) * 1000}}
                : nlohmann::json{{"sec", us / 1'000'000}, {"nsec", (us % 1'000'000) * 1000}};
  };
  auto hdr = [&](int64_t us, int64_t seq) {
    nlohmann::json h = {{"stamp", time_msg(us)}, {"frame_id", ""}};
    if (!ros2) h["seq"] = seq;
    return h;
  };
  std::vector<nlohmann::json> msgs;
  auto add = [&](const std::string& topic, const std::string& type, int64_t arrival_us, nlohmann::json msg) {
    msgs.push_back({{"topic", topic}, {"type", type}, {"time_ns", arrival_us * 1000}, {"sequence", 0}, {"msg", msg}});
  };
  uint64_t n = 0;
  int64_t plans = 0;
  const std::string joint_state_type = ros2 ? "sensor_msgs/msg/JointState" : "sensor_msgs/JointState";
  for (double start = 0.5; start + 2 <= duration_s; start += 2) {
    nlohmann::json points = nlohmann::json::array();
    for (int k = 0; k <= 20; ++k) {
      const double t = start + 0.1 * k;
      std::vector<double> pos, vel;
      for (size_t j = 0; j < joints.size(); ++j) pos.push_back(q(j, t)), vel.push_back(qd(j, t));
      points.push_back({{"positions", pos},
                        {"velocities", vel},
                        {"accelerations", std::vector<double>()},
                        {"effort", std::vector<double>()},
                        {"time_from_start", time_msg(int64_t{100'000} * k)}});
    }
    const int64_t sent = wall0 + std::llround(start * 1e6);
    const nlohmann::json trajectory = {{"header", hdr(0, plans)}, {"joint_names", joints}, {"points", points}};
    if (ros2) {
      add("/arm_controller/joint_trajectory", "trajectory_msgs/msg/JointTrajectory", sent, trajectory);
    } else {
      add("/arm_controller/follow_joint_trajectory/goal", "control_msgs/FollowJointTrajectoryActionGoal", sent,
          {{"header", hdr(sent, plans)},
           {"goal_id", {{"stamp", time_msg(sent)}, {"id", "goal-" + std::to_string(plans)}}},
           {"goal",
            {{"trajectory", trajectory},
             {"path_tolerance", nlohmann::json::array()},
             {"goal_tolerance",
              nlohmann::json::array(
                  {{{"name", joints[0]}, {"position", 0.01}, {"velocity", 0.0}, {"acceleration", 0.0}}})},
             {"goal_time_tolerance", time_msg(500'000)}}}});
    }
    ++plans;
  }
  int64_t seq = 0;
  for (int64_t ms = 0; ms < std::llround(duration_s * 1000); ms += 10) {
    const double t = static_cast<double>(ms) * 1e-3;
    std::vector<double> pos, vel, effort;
    for (size_t j = 0; j < joints.size(); ++j) {
      pos.push_back(q(j, t - delay_ms * 1e-3));
      vel.push_back(qd(j, t - delay_ms * 1e-3));
      effort.push_back(0.0);
    }
    const int64_t stamp = wall0 + ms * 1000;
    // Around 20 s a burst: ten states held up 30 ms and delivered after newer ones.
    const double held = (ms >= 20'000 && ms < 20'100) ? 30 : 0;
    add("/joint_states", joint_state_type, stamp + std::llround((0.5 + held + jitter_ms(++n)) * 1e3),
        {{"header", hdr(stamp, seq)}, {"name", joints}, {"position", pos}, {"velocity", vel}, {"effort", effort}});
    if (controller != Controller::kNone) {
      std::vector<double> ref, ref_vel, err;
      for (size_t j = 0; j < joints.size(); ++j) {
        ref.push_back(q(j, t - (delay_ms - tracking_lag_ms) * 1e-3));
        ref_vel.push_back(qd(j, t - (delay_ms - tracking_lag_ms) * 1e-3));
        err.push_back(ref[j] - pos[j]);
      }
      auto point = [&](const std::vector<double>& p, const std::vector<double>& v) {
        return nlohmann::json{{"positions", p},
                              {"velocities", v},
                              {"accelerations", std::vector<double>()},
                              {"effort", std::vector<double>()},
                              {"time_from_start", time_msg(0)}};
      };
      const std::vector<double> none;
      nlohmann::json state = {{"header", hdr(stamp, seq)}, {"joint_names", joints}};
      if (controller == Controller::kBeforeHumble) {
        state["desired"] = point(ref, ref_vel), state["actual"] = point(pos, vel), state["error"] = point(err, none);
      } else {
        state["reference"] = point(ref, ref_vel), state["feedback"] = point(pos, vel);
        state["error"] = point(err, none), state["output"] = point(none, ref_vel);
        state["multi_dof_joint_names"] = nlohmann::json::array();
        std::vector<std::string> multi = {"reference", "feedback", "error", "output"};
        if (controller == Controller::kHumble) {
          state["desired"] = point(ref, ref_vel), state["actual"] = point(pos, vel);
          multi.insert(multi.end(), {"desired", "actual"});
        }
        for (const auto& f : multi) {
          state["multi_dof_" + f] = {{"transforms", nlohmann::json::array()},
                                     {"velocities", nlohmann::json::array()},
                                     {"accelerations", nlohmann::json::array()},
                                     {"time_from_start", time_msg(0)}};
        }
      }
      add(ros2 ? "/arm_controller/controller_state" : "/arm_controller/state",
          ros2 ? "control_msgs/msg/JointTrajectoryControllerState" : "control_msgs/JointTrajectoryControllerState",
          stamp + std::llround((0.3 + jitter_ms(++n)) * 1e3), state);
    }
    ++seq;
  }
  std::stable_sort(msgs.begin(), msgs.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
    return a["time_ns"].get<int64_t>() < b["time_ns"].get<int64_t>();
  });
  nlohmann::json spec = {{"profile", ros2 ? "ros2" : "ros1"}, {"compression", "zstd"}, {"messages", msgs}};
  // control_msgs before Humble (ROS 2 Foxy, Galactic) had ROS 1's three points; Jazzy dropped the deprecated two.
  const std::string point = "trajectory_msgs/JointTrajectoryPoint ";
  const std::string multi = "trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_";
  const std::string head = "std_msgs/Header header\nstring[] joint_names\n";
  if (ros2 && controller == Controller::kBeforeHumble) {
    spec["definitions"]["control_msgs/JointTrajectoryControllerState"] =
        head + point + "desired\n" + point + "actual\n" + point + "error\n";
  }
  if (ros2 && controller == Controller::kJazzy) {
    spec["definitions"]["control_msgs/JointTrajectoryControllerState"] =
        head + point + "reference\n" + point + "feedback\n" + point + "error\n" + point + "output\n" +
        "string[] multi_dof_joint_names\n" + multi + "reference\n" + multi + "feedback\n" + multi + "error\n" + multi +
        "output\n";
  }
  return spec;
}

// The arm on a real recording (issue 26): MoveIt's plans imported as joint trajectories, the loop delay measured
// from the motion within 5 ms of the injected 120 ms (the calibration's yardstick, docs/diagnosis.md), a fault of the
// command stream, and the headline's worst stream: the cause (a late loop) before another stream's symptom
// (reordered joint states). Written as ROS 2 topics and as ROS 1 action goals.
TEST(DiagnoseArmBag, TheLoopDelayIsTheCommandStreamsFaultAndTheHeadline) {
  for (const bool ros2 : {true, false}) {
    SCOPED_TRACE(ros2 ? "ROS 2" : "ROS 1");
    constexpr double kDelayMs = 120;
    test::TempDir dir;
    Diagnosis d;
    if (!diagnose_bag(arm_bag(ros2, kDelayMs, 40), dir, &d)) return;
    const std::string command =
        ros2 ? "/arm_controller/joint_trajectory" : "/arm_controller/follow_joint_trajectory/goal";
    ASSERT_EQ(d.command_loops.size(), 1u);
    const auto& loop = d.command_loops[0];
    EXPECT_EQ(loop.command_channel, command);
    EXPECT_EQ(loop.state_channel, "/joint_states");
    ASSERT_TRUE(loop.delay_valid) << loop.confidence;
    EXPECT_NEAR(loop.delay_s * 1e3, kDelayMs, 5.0);
    const auto& cmd = channel(d, command);
    EXPECT_EQ(cmd.type, "driftlab.joint_trajectory_t");
    EXPECT_EQ(cmd.verdict, "fault") << reasons(cmd);
    ASSERT_FALSE(cmd.reasons.empty());
    EXPECT_NE(cmd.reasons[0].find("follow its commands"), std::string::npos) << reasons(cmd);
    EXPECT_EQ(channel(d, "/joint_states").verdict, "fault") << reasons(channel(d, "/joint_states"));  // reordered
    const ChannelTiming* worst = worst_stream(d);
    ASSERT_NE(worst, nullptr);
    EXPECT_EQ(worst->name, command) << reasons(*worst);
  }
  // The same arm without a delay: no loop problem (the simulator's clean arm follows 0.2 ms late).
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(arm_bag(true, 0, 40), dir, &d)) return;
  ASSERT_EQ(d.command_loops.size(), 1u);
  EXPECT_NEAR(d.command_loops[0].delay_s * 1e3, 0, 5.0);
  EXPECT_FALSE(has_reason(channel(d, "/arm_controller/joint_trajectory"), "follow its commands"));
}

// ros2_control's controller state (control_msgs/JointTrajectoryControllerState) in each release's layout, written
// by Foxglove's writers: imported as driftlab.joint_trajectory_state_t with the reference, feedback and output
// written (to the last bit: no arithmetic on the way), and `eval --arm --arm-reference desired` measuring the
// controller's own tracking lag (20 ms) apart from the commands' whole loop (120 ms).
TEST(ImportArmBag, TheControllerStateOfEveryReleaseIsTheDesiredAndTheActualJoints) {
  const struct {
    bool ros2;
    Controller controller;
    const char* name;
  } kCases[] = {{false, Controller::kBeforeHumble, "ROS 1"},
                {true, Controller::kBeforeHumble, "ROS 2 Foxy"},
                {true, Controller::kHumble, "ROS 2 Humble"},
                {true, Controller::kJazzy, "ROS 2 Jazzy"}};
  constexpr double kDelayMs = 120, kLagMs = 20;
  for (const auto& c : kCases) {
    SCOPED_TRACE(c.name);
    test::TempDir dir;
    const nlohmann::json spec = arm_bag(c.ros2, kDelayMs, 12, c.controller, kLagMs);
    const std::string bag = dir.file("arm.mcap"), log = dir.file("arm.lcm");
    if (!test::oracle_write_mcap(spec, bag)) return;
    auto imported = formats::import_log(bag, log, [](const std::string& p) { ADD_FAILURE() << p; });
    ASSERT_TRUE(imported.ok()) << imported.error().message;
    const std::string topic = c.ros2 ? "/arm_controller/controller_state" : "/arm_controller/state";
    std::vector<nlohmann::json> written;
    for (const auto& m : spec["messages"]) {
      if (m["topic"] == topic) written.push_back(m["msg"]);
    }
    size_t k = 0;
    for (const auto& e : test::read_all(log)) {
      if (e.channel != topic) continue;
      const auto s = test::decode<driftlab::joint_trajectory_state_t>(e);
      ASSERT_LT(k, written.size());
      const auto& w = written[k++];
      const bool v1 = !w.contains("reference");
      const auto& ref = w[v1 ? "desired" : "reference"];
      const auto& fb = w[v1 ? "actual" : "feedback"];
      EXPECT_EQ(s.joint_names, w["joint_names"].get<std::vector<std::string>>());
      EXPECT_EQ(s.desired_positions, ref["positions"].get<std::vector<double>>());
      EXPECT_EQ(s.desired_velocities, ref["velocities"].get<std::vector<double>>());
      EXPECT_EQ(s.actual_positions, fb["positions"].get<std::vector<double>>());
      EXPECT_EQ(s.actual_velocities, fb["velocities"].get<std::vector<double>>());
      if (v1) {  // no output in the message: the commands are not known
        EXPECT_TRUE(std::all_of(s.commands.begin(), s.commands.end(), [](double v) { return std::isnan(v); }));
      } else {
        EXPECT_EQ(s.commands, w["output"]["velocities"].get<std::vector<double>>());
      }
      EXPECT_EQ(s.following, 1);
    }
    ASSERT_FALSE(written.empty());
    EXPECT_EQ(k, written.size());
    // The joints against the controller's desired state trail it by the controller's lag alone; against the
    // commands' plans, by the whole loop. A joint's mean |error| is its lag times its mean |speed| (the first
    // joint: 0.6 rad at 0.3 Hz, 0.72 rad/s on average); 25% is the plan's interpolation between its 100 ms
    // points (second order: under 1% here) and the first plan's start, with margin.
    analyzers::ArmTrackingOptions options;
    options.reference = analyzers::ArmReference::kDesired;
    auto desired = analyzers::evaluate_arm(log, options);
    ASSERT_TRUE(desired.ok()) << desired.error().message;
    EXPECT_EQ(desired->controller_channel, topic);
    auto commanded = analyzers::evaluate_arm(log);
    ASSERT_TRUE(commanded.ok()) << commanded.error().message;
    const double mean_speed = 0.6 * 2 * M_PI * 0.3 * 2 / M_PI;
    ASSERT_FALSE(desired->joints.empty());
    ASSERT_FALSE(commanded->joints.empty());
    EXPECT_NEAR(desired->joints[0].error_rad.mean, kLagMs * 1e-3 * mean_speed, 0.25 * kLagMs * 1e-3 * mean_speed);
    EXPECT_NEAR(commanded->joints[0].error_rad.mean, kDelayMs * 1e-3 * mean_speed, 0.25 * kDelayMs * 1e-3 * mean_speed);
  }
}

/// A MAVROS-style bag on the wall clock: the flight controller's IMU at 100 Hz and local position at 30 Hz (1 and
/// 2 ms of transport), its state (mavros_msgs/State, a type driftlab has no mapping for) at 5 Hz stamped
/// `state_late_ms` before it arrives, and the time sync's status at 10 Hz: round trips of 15 ms, its offset
/// estimate 2.5 ms, restarted once at 30 s (stepping to 40 ms).
nlohmann::json mavros_bag(double state_late_ms) {
  const int64_t wall0 = 1'780'000'000'000'000;
  std::vector<nlohmann::json> msgs;
  auto add = [&](const std::string& topic, const std::string& type, int64_t arrival_us, nlohmann::json msg) {
    msgs.push_back({{"topic", topic}, {"type", type}, {"time_ns", arrival_us * 1000}, {"sequence", 0}, {"msg", msg}});
  };
  uint64_t n = 0;
  for (int64_t ms = 10; ms < 60'000; ms += 10) {
    const int64_t stamp = wall0 + ms * 1000;
    auto arrive = [&](double extra_ms) { return stamp + std::llround((extra_ms + jitter_ms(++n)) * 1e3); };
    add("/mavros/imu/data", "sensor_msgs/msg/Imu", arrive(1),
        {{"header", header(stamp, "base_link")},
         {"orientation", quat()},
         {"orientation_covariance", std::vector<double>(9, 0.0)},
         {"angular_velocity", vec3(0, 0, 0.2 * std::sin(ms * 1e-3))},
         {"angular_velocity_covariance", std::vector<double>(9, 0.0)},
         {"linear_acceleration", vec3(0, 0, 9.81)},
         {"linear_acceleration_covariance", std::vector<double>(9, 0.0)}});
    if (ms % 30 == 0) {
      add("/mavros/local_position/pose", "geometry_msgs/msg/PoseStamped", arrive(2),
          {{"header", header(stamp, "map")}, {"pose", {{"position", vec3(ms * 1e-3)}, {"orientation", quat()}}}});
    }
    if (ms % 200 == 0) {
      add("/mavros/state", "mavros_msgs/msg/State", arrive(state_late_ms),
          {{"header", header(stamp, "")},
           {"connected", true},
           {"armed", ms > 5000},
           {"guided", true},
           {"manual_input", false},
           {"mode", "OFFBOARD"},
           {"system_status", 4}});
    }
    if (ms % 100 == 0) {
      const double offset_ms = ms < 30'000 ? 2.5 : 40.0;
      add("/mavros/timesync_status", "mavros_msgs/msg/TimesyncStatus", arrive(0.3),
          {{"header", header(stamp, "")},
           {"remote_timestamp_ns", std::to_string((stamp + std::llround(offset_ms * 1e3)) * 1000) + "n"},
           {"observed_offset_ns", std::to_string(std::llround((offset_ms + 0.1 * std::sin(ms)) * 1e6)) + "n"},
           {"estimated_offset_ns", std::to_string(std::llround(offset_ms * 1e6)) + "n"},
           {"round_trip_time_ms", 15.0}});
    }
  }
  std::stable_sort(msgs.begin(), msgs.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
    return a["time_ns"].get<int64_t>() < b["time_ns"].get<int64_t>();
  });
  return {{"profile", "ros2"}, {"compression", "zstd"}, {"messages", msgs}};
}

// Any stamped message (issue 26): mavros_msgs/State has no mapping, and its std_msgs/Header gets it the whole
// timing analysis (its 110 ms latency within 3 ms: 1 ms of jitter on a 1 ms transport); `info` names its ROS type.
// The time sync (mavros_msgs/TimesyncStatus): its round trip, offset and restart, the restart its fault.
TEST(DiagnoseMavrosBag, AStampedMessageOfAnyTypeAndTheTimeSync) {
  constexpr double kStateLateMs = 110;
  test::TempDir dir;
  Diagnosis d;
  if (!diagnose_bag(mavros_bag(kStateLateMs), dir, &d)) return;
  const auto& state = channel(d, "/mavros/state");
  EXPECT_EQ(state.type, "driftlab.stamped_foreign_message_t");
  EXPECT_EQ(state.source_type, "mavros_msgs/msg/State");
  ASSERT_TRUE(state.has_header);
  ASSERT_TRUE(state.latency_valid);
  EXPECT_NEAR(state.latency_s.p50 * 1e3, kStateLateMs, 3.0);
  // Named late against the typical stream on the recorder's clock (the IMU's 1 ms and the position's 2 ms of
  // transport, the time sync's 0.3 ms: the median 1 to 2 ms), by its amount within 3 ms; the others are not.
  std::string said;
  for (const auto& r : state.reasons) said += r.find("after the typical stream") != std::string::npos ? r : "";
  double late_ms = 0;
  ASSERT_EQ(
      std::sscanf(said.c_str(), "arrives %lf ms after the typical stream on its clock (the recorder's)", &late_ms), 1)
      << reasons(state);
  EXPECT_NEAR(late_ms, kStateLateMs, 3.0);
  for (const char* other : {"/mavros/imu/data", "/mavros/local_position/pose", "/mavros/timesync_status"}) {
    EXPECT_FALSE(has_reason(channel(d, other), "after the typical stream")) << other;
  }
  EXPECT_TRUE(state.seq_counted);
  EXPECT_EQ(state.missing_by_period, 0);

  ASSERT_EQ(d.timesync.size(), 1u);
  const auto& sync = d.timesync[0];
  EXPECT_EQ(sync.channel, "/mavros/timesync_status");
  EXPECT_NEAR(sync.round_trip_s.p50, 0.015, 1e-6);
  EXPECT_NEAR(sync.offset_first_s, 0.0025, 1e-9);
  EXPECT_NEAR(sync.offset_last_s, 0.040, 1e-9);
  EXPECT_EQ(sync.resyncs, 1);
  ASSERT_EQ(sync.resync_at_s.size(), 1u);
  EXPECT_NEAR(sync.resync_at_s[0], 30.0, 0.02);
  const auto& ts = channel(d, "/mavros/timesync_status");
  EXPECT_EQ(ts.verdict, "fault") << reasons(ts);
  EXPECT_TRUE(has_reason(ts, "started over 1 times")) << reasons(ts);
  EXPECT_TRUE(has_reason(ts, "round trips take 15.0 ms")) << reasons(ts);
  EXPECT_EQ(channel(d, "/mavros/imu/data").verdict, "ok") << reasons(channel(d, "/mavros/imu/data"));

  // info: the ROS type beside driftlab's.
  auto info = analyzers::log_info(dir.file("run.lcm"));
  ASSERT_TRUE(info) << info.error().message;
  const std::string text = analyzers::log_info_text(*info, 20);
  EXPECT_NE(text.find("source type"), std::string::npos) << text;
  std::string state_line;
  for (size_t at = text.find("/mavros/state"); at != std::string::npos && state_line.empty();) {
    state_line = text.substr(at, text.find('\n', at) - at);
  }
  EXPECT_NE(state_line.find("driftlab.stamped_foreign_message_t  mavros_msgs/msg/State"), std::string::npos) << text;
}

}  // namespace
}  // namespace driftlab
