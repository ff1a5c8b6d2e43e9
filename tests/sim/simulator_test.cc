// Simulation::create / run on the default indoor scenario: every stream at its rate, deterministic bytes, ground
// truth, sensors that agree with the world and the motion, faults that change what a system sees (scored by
// `driftlab diagnose`), the fault manifest, and a 3D lidar.
#include "sim/simulator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "analyzers/timing.h"
#include "driftlab/fault_manifest_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "sim/raycaster.h"
#include "tests/test_util.h"
#include "lcmtypes/planar.h"

namespace driftlab::sim {
namespace {

using test::decode;

constexpr double kSeconds = 20;

Scenario default_scenario(double seconds = kSeconds) {
  auto sc = load_scenario(default_scenario_path());
  EXPECT_TRUE(sc.ok()) << (sc.ok() ? "" : sc.error().message);
  sc->duration = seconds;
  return *sc;
}

SimReport run_ok(const Scenario& sc, const std::string& out) {
  auto sim = Simulation::create(sc);
  EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
  SimOptions o;
  o.out = out;
  auto r = (*sim)->run(o);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  return *r;
}

/// One 20 s run of the default scenario, shared by the tests that only read it.
class DefaultRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    report_ = new SimReport(run_ok(default_scenario(), dir_->file("sim.lcm")));
    std::vector<Problem> problems;
    events_ = new std::vector<test::OwnedEvent>(test::read_all(dir_->file("sim.lcm"), &problems));
    EXPECT_TRUE(problems.empty());
  }
  static void TearDownTestSuite() {
    delete events_;
    delete report_;
    delete dir_;
  }
  static std::vector<const test::OwnedEvent*> on(const std::string& channel) {
    std::vector<const test::OwnedEvent*> out;
    for (const auto& e : *events_) {
      if (e.channel == channel) out.push_back(&e);
    }
    return out;
  }
  /// Ground truth (x, y, yaw) at true time t [us], linearly interpolated.
  static Eigen::Vector3d truth_at(int64_t t) {
    const auto gt = on("GROUND_TRUTH");
    for (std::size_t i = 1; i < gt.size(); ++i) {
      const auto b = decode<driftlab::pose_t>(*gt[i]);
      if (b.header.utime < t) continue;
      const auto a = decode<driftlab::pose_t>(*gt[i - 1]);
      const double u = static_cast<double>(t - a.header.utime) / static_cast<double>(b.header.utime - a.header.utime);
      const double ya = yaw_of(a.orientation), yb = yaw_of(b.orientation);
      return {a.position.x + u * (b.position.x - a.position.x), a.position.y + u * (b.position.y - a.position.y),
              ya + u * std::remainder(yb - ya, 2 * M_PI)};
    }
    return {NAN, NAN, NAN};
  }
  static test::TempDir* dir_;
  static SimReport* report_;
  static std::vector<test::OwnedEvent>* events_;
};
test::TempDir* DefaultRun::dir_ = nullptr;
SimReport* DefaultRun::report_ = nullptr;
std::vector<test::OwnedEvent>* DefaultRun::events_ = nullptr;

TEST_F(DefaultRun, EveryStreamAtItsRateInArrivalOrder) {
  EXPECT_FALSE(report_->interrupted);
  EXPECT_DOUBLE_EQ(report_->simulated_s, kSeconds);
  // Streams without faults: exactly rate * duration + 1 messages, seq from 0 without gaps.
  const std::map<std::string, int64_t> expected = {{"GROUND_TRUTH", 2001}, {"IMU", 4001}, {"JOINT_STATES", 1001},
                                                   {"CAMERA", 101},        {"CMD", 401},   {"TF", 1001},
                                                   {"TF_STATIC", 21},      {"ODOM", 1001}};
  for (const auto& [channel, n] : expected) EXPECT_EQ(report_->messages.at(channel), n) << channel;
  EXPECT_EQ(report_->messages.at("FAULTS"), 1);
  // Lidar scans complete 10 per second; some were dropped by the injected faults.
  EXPECT_GT(report_->messages.at("SCAN"), 150);
  EXPECT_LT(report_->messages.at("SCAN"), 200);
  int64_t last = 0;
  for (const auto& e : *events_) {
    EXPECT_GE(e.utime, last) << e.channel;
    last = e.utime;
  }
  EXPECT_EQ(events_->back().channel, "FAULTS");
  int64_t seq = 0;
  for (const auto* e : on("GROUND_TRUTH")) EXPECT_EQ(decode<driftlab::pose_t>(*e).header.seq, seq++);
}

TEST_F(DefaultRun, GroundTruthFollowsTheRouteAndOdometryDrifts) {
  const auto gt = on("GROUND_TRUTH");
  const auto first = decode<driftlab::pose_t>(*gt.front());
  const auto last = decode<driftlab::pose_t>(*gt.back());
  EXPECT_EQ(first.header.frame_id, "world");
  EXPECT_EQ(first.child_frame_id, "base_link");
  EXPECT_NEAR(first.position.x, 2.0, 0.01);
  EXPECT_NEAR(first.position.y, 5.5, 0.01);
  // Along the corridor's eastbound lane at up to 0.4 m/s.
  EXPECT_GT(last.position.x, 8.0);
  EXPECT_NEAR(last.position.y, 5.5, 0.3);
  EXPECT_GT(report_->distance_m, 6.0);
  EXPECT_LT(report_->distance_m, 8.1);
  // The odometry (calibrated 0.3% off, with slip) is off the truth, but not by much yet.
  EXPECT_GT(report_->odometry_error_m, 0.005);
  EXPECT_LT(report_->odometry_error_m, 0.3);
  const auto odom = decode<driftlab::odometry_t>(*on("ODOM").back());
  EXPECT_EQ(odom.header.frame_id, "odom");
  EXPECT_NEAR(odom.position.x, last.position.x - 2.0, 0.3);
  // TF carries odom -> base_link; TF_STATIC the sensor frames.
  const auto tf = decode<driftlab::tf_t>(*on("TF").back());
  ASSERT_EQ(tf.ntransforms, 1);
  EXPECT_EQ(tf.transforms[0].child_frame_id, "base_link");
  const auto st = decode<driftlab::tf_t>(*on("TF_STATIC").front());
  std::set<std::string> children;
  for (const auto& t : st.transforms) children.insert(t.child_frame_id);
  EXPECT_EQ(children, (std::set<std::string>{"laser", "imu_link", "camera_link", "odom"}));  // world -> odom
}

TEST_F(DefaultRun, ScansSeeTheWorldFromTheTruePose) {
  auto world = load_world(std::string(DRIFTLAB_SOURCE_DIR) + "/sim/worlds/building.yaml");
  ASSERT_TRUE(world.ok());
  RayCaster caster(*world);
  int compared = 0, close = 0;
  for (const auto* e : on("SCAN")) {
    const auto scan = decode<driftlab::laser_scan_t>(*e);
    ASSERT_EQ(scan.nranges, 360);
    EXPECT_EQ(scan.header.frame_id, "laser");
    for (int i = 0; i < scan.nranges; i += 7) {
      if (!std::isfinite(scan.ranges[i])) continue;
      // Beam i was measured at stamp + i * time_increment from the laser's pose then (x 0.08, z 0.18 on the base).
      const auto t = scan.header.utime + static_cast<int64_t>(i * scan.time_increment * 1e6);
      const Eigen::Vector3d p = truth_at(t);
      if (!std::isfinite(p.x())) continue;
      const Eigen::Vector3d origin(p.x() + 0.08 * std::cos(p.z()), p.y() + 0.08 * std::sin(p.z()), 0.08 + 0.18);
      const double a = p.z() + scan.angle_min + i * scan.angle_increment;
      const double expected = caster.range(origin, {std::cos(a), std::sin(a), 0}, 30);
      ++compared;
      if (std::abs(expected - scan.ranges[i]) < 0.05) ++close;
    }
  }
  ASSERT_GT(compared, 5000);
  EXPECT_GT(static_cast<double>(close) / compared, 0.97);  // a few beams graze edges between ground-truth samples
}

TEST_F(DefaultRun, ImuMeasuresTheMotion) {
  const auto imu = on("IMU");
  double sum_az = 0, sum_err = 0;
  int n = 0;
  for (std::size_t i = 100; i + 1 < imu.size(); i += 10) {
    const auto m = decode<driftlab::imu_t>(*imu[i]);
    EXPECT_EQ(m.header.frame_id, "imu_link");
    sum_az += m.linear_acceleration.z;
    // The IMU's clock is 15 ms ahead: true time = stamp - 15 ms. Yaw rate from the truth around then.
    const int64_t t = m.header.utime - 15000;
    const double rate = std::remainder(truth_at(t + 20000).z() - truth_at(t - 20000).z(), 2 * M_PI) / 0.04;
    sum_err += std::abs(m.angular_velocity.z - rate);
    ++n;
  }
  EXPECT_NEAR(sum_az / n, 9.81, 0.05);
  EXPECT_LT(sum_err / n, 0.02);  // [rad/s]: noise, bias and the finite difference
}

TEST_F(DefaultRun, FaultsChangeStampsArrivalsAndSeq) {
  // IMU: the source clock is 15 ms ahead; it arrives at once.
  for (const auto* e : on("IMU")) {
    ASSERT_EQ(decode<driftlab::imu_t>(*e).header.utime - e->utime, 15000);
  }
  // ODOM: stamps in true time, arrivals 1 ms plus jitter later.
  for (const auto* e : on("ODOM")) ASSERT_GE(e->utime - decode<driftlab::odometry_t>(*e).header.utime, 1000);
  // SCAN: the missing seqs are exactly the manifest's drops.
  std::set<int64_t> seen;
  for (const auto* e : on("SCAN")) seen.insert(decode<driftlab::laser_scan_t>(*e).header.seq);
  const auto manifest = decode<driftlab::fault_manifest_t>(*on("FAULTS").front());
  std::set<int64_t> dropped;
  for (const auto& f : manifest.faults) {
    if (f.channel == "SCAN" && (f.kind == "drop" || f.kind == "burst_drop")) {
      dropped.insert(f.affected_seq.begin(), f.affected_seq.end());
    }
  }
  EXPECT_FALSE(dropped.empty());
  const int64_t scans = static_cast<int64_t>(seen.size() + dropped.size());
  for (int64_t s = 0; s < scans; ++s) EXPECT_NE(seen.count(s), dropped.count(s)) << "seq " << s;
  // The same manifest as JSON beside the log.
  std::ifstream f(report_->faults_json);
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["faults"].size(), manifest.faults.size());
  EXPECT_EQ(j["seed"], 1);
  bool found = false;
  for (const auto& fj : j["faults"]) {
    if (fj["channel"] == "IMU" && fj["kind"] == "clock_offset") {
      EXPECT_DOUBLE_EQ(fj["params"]["offset_s"].get<double>(), 0.015);
      found = true;
    }
  }
  EXPECT_TRUE(found);
}

TEST_F(DefaultRun, DiagnoseFindsTheInjectedFaults) {
  auto d = analyzers::diagnose(dir_->file("sim.lcm"));
  ASSERT_TRUE(d.ok()) << d.error().message;
  std::map<std::string, const analyzers::ChannelTiming*> by;
  for (const auto& c : d->channels) by[c.name] = &c;
  EXPECT_NEAR(by.at("IMU")->clock_offset_s, 0.015, 0.001);
  EXPECT_EQ(by.at("IMU")->verdict, "fault");
  EXPECT_EQ(by.at("SCAN")->seq_gaps, 1 + decode<driftlab::laser_scan_t>(*on("SCAN").back()).header.seq -
                                         static_cast<int64_t>(on("SCAN").size()));
  EXPECT_GT(by.at("ODOM")->latency_s.p99, 0.005);
  EXPECT_EQ(by.at("GROUND_TRUTH")->verdict, "ok");
}

TEST_F(DefaultRun, CameraAndJointStates) {
  const auto img = decode<driftlab::image_t>(*on("CAMERA").back());
  EXPECT_EQ(img.encoding, "jpeg");
  const cv::Mat m = cv::imdecode(img.data, cv::IMREAD_COLOR);
  ASSERT_FALSE(m.empty());
  EXPECT_EQ(m.cols, 320);
  EXPECT_EQ(m.rows, 240);
  cv::Scalar mean, stddev;
  cv::meanStdDev(m, mean, stddev);
  EXPECT_GT(stddev[0], 10);  // a picture, not a flat colour
  const auto js = decode<driftlab::joint_state_t>(*on("JOINT_STATES").back());
  ASSERT_EQ(js.njoints, 2);
  EXPECT_EQ(js.name[0], "left_wheel_joint");
  EXPECT_GT(js.position[0], 50);  // [rad] after ~7 m on 8 cm wheels
  EXPECT_NEAR(js.velocity[0], 5, 1);
}

TEST(Simulation, SameScenarioAndSeedGiveTheSameBytes) {
  test::TempDir dir;
  const Scenario sc = default_scenario(4);
  run_ok(sc, dir.file("a.lcm"));
  run_ok(sc, dir.file("b.lcm"));
  Scenario other = sc;
  other.seed = other.faults.seed = 2;
  run_ok(other, dir.file("c.lcm"));
  const auto a = test::read_file(dir.file("a.lcm")), b = test::read_file(dir.file("b.lcm"));
  EXPECT_GT(a.size(), 500000u);
  EXPECT_TRUE(a == b);
  EXPECT_FALSE(a == test::read_file(dir.file("c.lcm")));
  EXPECT_EQ(test::read_file(dir.file("a.faults.json")), test::read_file(dir.file("b.faults.json")));
}

// A clock fault moves every stamp a message carries: a tf_t's transforms have stamps of their own, and TF
// consumers look them up by those (they stayed on true time while the header moved).
TEST(Simulation, AClockFaultMovesEveryStampATfMessageCarries) {
  test::TempDir dir;
  Scenario sc = default_scenario(2);
  sc.faults.streams.clear();
  sc.faults.streams["TF"].clock_offset_s = 0.25;
  run_ok(sc, dir.file("tf.lcm"));
  int n = 0;
  for (const auto& e : test::read_all(dir.file("tf.lcm"))) {
    if (e.channel != "TF") continue;
    const auto tf = decode<driftlab::tf_t>(e);
    ASSERT_EQ(tf.header.utime - e.utime, 250000);
    ASSERT_EQ(tf.ntransforms, 1);
    EXPECT_EQ(tf.transforms[0].header.utime, tf.header.utime);
    ++n;
  }
  EXPECT_GT(n, 50);
}

// A log carries the scenario as it was run (the SIMULATION message): run again from the log alone, the
// simulation writes the same log, byte for byte (what `driftlab replay --closed-loop` starts from).
TEST(Simulation, ALogCarriesItsScenarioAndRunsAgainTheSame) {
  test::TempDir dir;
  Scenario sc = default_scenario(2);
  sc.seed = 7;
  sc.faults.seed = 9;
  run_ok(sc, dir.file("a.lcm"));
  auto again = scenario_of_log(dir.file("a.lcm"));
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(again->duration, 2);
  EXPECT_EQ(again->seed, 7u);
  EXPECT_EQ(again->faults.seed, 9u);
  run_ok(*again, dir.file("b.lcm"));
  EXPECT_EQ(test::read_file(dir.file("a.lcm")), test::read_file(dir.file("b.lcm")));
  const auto none = scenario_of_log(std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm");
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no SIMULATION message"), std::string::npos);
}

TEST(Simulation, StopRequestClosesAValidLog) {
  test::TempDir dir;
  const Scenario sc = default_scenario(600);
  auto sim = Simulation::create(sc);
  ASSERT_TRUE(sim.ok());
  std::atomic<bool> stop{false};
  SimOptions o;
  o.out = dir.file("cut.lcm");
  o.stop = &stop;
  o.progress = [&stop](double done, double) { stop = done >= 3.0; };
  auto r = (*sim)->run(o);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->interrupted);
  EXPECT_NEAR(r->simulated_s, 3.0, 0.01);
  std::vector<Problem> problems;
  const auto events = test::read_all(dir.file("cut.lcm"), &problems);
  EXPECT_TRUE(problems.empty());
  EXPECT_EQ(events.back().channel, "FAULTS");
  EXPECT_GT(events.size(), 1000u);
  EXPECT_FALSE(std::ifstream(dir.file("cut.lcm.partial")).good());
}

TEST(Simulation, FloorPlanWorld) {
  test::TempDir dir;
  auto sc = load_scenario(std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/warehouse.yaml");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  EXPECT_GT(sc->world.boxes.size(), 10u);  // walls, shelves and pillars from the image
  sc->duration = 3;
  run_ok(*sc, dir.file("w.lcm"));
  int scans = 0;
  for (const auto& e : test::read_all(dir.file("w.lcm"))) {
    if (e.channel != "SCAN") continue;
    const auto scan = decode<driftlab::laser_scan_t>(e);
    int valid = 0;
    for (float r : scan.ranges) valid += std::isfinite(r) ? 1 : 0;
    EXPECT_EQ(valid, scan.nranges);  // enclosed by the plan's walls: every beam returns
    // Start (4.5, 2.5) facing +x: the south wall (inner face y = 0.2) is 2.3 m to the right of the laser.
    if (scans++ == 0) {
      EXPECT_NEAR(scan.ranges[180], 2.3, 0.05);
    }
  }
  EXPECT_EQ(scans, 30);
}

TEST(Simulation, ThreeDimensionalLidar) {
  test::TempDir dir;
  auto sc = load_scenario(std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/indoor_3d.yaml");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  sc->duration = 1;
  run_ok(*sc, dir.file("3d.lcm"));
  int clouds = 0;
  for (const auto& e : test::read_all(dir.file("3d.lcm"))) {
    if (e.channel != "POINTS") continue;
    const auto c = decode<driftlab::point_cloud_t>(e);
    ASSERT_EQ(c.height, 16);
    ASSERT_EQ(c.width, 1800);
    ASSERT_EQ(c.npoints, 16 * 1800);
    ASSERT_EQ(c.ntimes, c.npoints);
    int valid = 0;
    for (int i = 0; i < c.npoints; ++i) {
      if (!std::isfinite(c.x[i])) continue;
      ++valid;
      // Every return lies on the floor, an obstacle or a wall: within the building, above the floor.
      ASSERT_GT(c.z[i], -0.55f) << i;  // the sensor is 0.48 m up; 2 cm range noise
      ASSERT_LT(std::hypot(c.x[i], c.y[i]), 25.0f);
    }
    EXPECT_GT(valid, c.npoints * 9 / 10);  // indoors nearly every beam hits something
    EXPECT_NEAR(c.time_offsets[c.npoints - 1], 0.1, 0.001);  // the last column at the end of the revolution
    ++clouds;
  }
  EXPECT_GE(clouds, 9);
}

}  // namespace
}  // namespace driftlab::sim
