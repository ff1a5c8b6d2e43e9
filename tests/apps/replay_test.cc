// End-to-end tests of `driftlab replay` on a simulated session: the estimator and controller modules, restamp auto
// against the simulator's IMU clock fault, injected faults, determinism, and bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/log_reader.h"
#include "core/log_writer.h"
#include "lcmtypes/stream_header.h"
#include "tests/doc_figures.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

test::CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

class ReplayCli : public ::testing::Test {
 protected:
  /// 60 s of the default scenario, with its faults (the IMU clock 15 ms ahead among them), made once.
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    const auto r = driftlab("sim --duration 60 -o " + log());
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string log() { return dir_->file("session.lcm"); }
  static std::string file(const std::string& name) { return dir_->file(name); }

  /// ATE RMSE [m] of LOG:CHANNEL against the session's ground truth, aligned in position and yaw.
  static double ate(const std::string& source) {
    const auto r = driftlab("eval --gt " + log() + ":GROUND_TRUTH --est " + source + " --align posyaw --json");
    EXPECT_EQ(r.code, 0) << r.err;
    return nlohmann::json::parse(r.out)["ate"]["rmse"].get<double>();
  }

  static test::TempDir* dir_;
};
test::TempDir* ReplayCli::dir_ = nullptr;

TEST_F(ReplayCli, EstimatorAndControllerRunOnASimulatedSession) {
  const auto r = driftlab("replay " + log() + " --modules estimator,controller --json -o " + file("r.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["read"].get<int64_t>(), j["dispatched"].get<int64_t>());
  EXPECT_NEAR(j["replayed_s"].get<double>(), 60, 0.1);
  ASSERT_EQ(j["modules"].size(), 2u);
  const auto& est = j["modules"][0];
  EXPECT_EQ(est["name"], "estimator");
  EXPECT_EQ(est["outputs"].get<int64_t>(), 3001);  // 50 Hz for 60 s, and the last state
  // The odometry arrives 1-20 ms late (latency and jitter) and the IMU's stamps run 15 ms ahead: the estimator
  // re-applies nearly every odometry message.
  EXPECT_GT(est["metrics"]["late_reapplied"].get<double>(), 2500);
  EXPECT_TRUE(est["warnings"].empty());
  const auto& ctl = j["modules"][1];
  EXPECT_EQ(ctl["name"], "controller");
  EXPECT_EQ(ctl["outputs"].get<int64_t>(), 1200 + 1);  // 20 Hz commands once odometry has come, and the comparison
  // The recomputed commands follow the logged ones closely: the same follower on the same odometry, but seeing
  // each odometry message only when it arrived.
  EXPECT_GT(ctl["metrics"]["compared_commands"].get<double>(), 1150);
  EXPECT_LT(ctl["metrics"]["angular_rmse_rad_s"].get<double>(), 0.05);
  EXPECT_LT(ctl["metrics"]["linear_rmse_m_s"].get<double>(), 0.02);
  // Fusing the gyro with the wheels beats the wheels alone.
  const double ekf = ate(file("r.lcm") + ":EKF_ODOM"), odom = ate(log() + ":ODOM");
  EXPECT_LT(ekf, odom);
  EXPECT_LT(ekf, 0.05);
}

TEST_F(ReplayCli, RestampAutoFindsTheImuClockAndLowersTheError) {
  const auto before = driftlab("replay " + log() + " --modules estimator -o " + file("before.lcm"));
  ASSERT_EQ(before.code, 0) << before.err;
  const auto after = driftlab("replay " + log() + " --modules estimator --restamp auto --json -o " + file("after.lcm"));
  ASSERT_EQ(after.code, 0) << after.err;
  const auto j = nlohmann::json::parse(after.out);
  ASSERT_TRUE(j["restamp"].contains("IMU")) << after.out;
  EXPECT_NEAR(j["restamp"]["IMU"]["offset_s"].get<double>(), 0.015, 0.001);
  EXPECT_EQ(j["restamp"].size(), 1u) << after.out;  // the other clocks are fine
  EXPECT_LT(ate(file("after.lcm") + ":EKF_ODOM"), ate(file("before.lcm") + ":EKF_ODOM"));
  // It says what it applied and from what (the notes' text: tests/analyzers/timing_test.cc, ClockCorrections).
  ASSERT_EQ(j["notes"].size(), 1u) << after.out;
  const std::string note = j["notes"][0];
  EXPECT_EQ(note.rfind("restamp IMU: +15.0 ms, +0 ppm (from the timing diagnosis of " + log() + ": offset 95% +", 0),
            0u)
      << note;
  const auto text = driftlab("replay " + log() + " --modules estimator --restamp auto -o " + file("after2.lcm"));
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_EQ(text.out.rfind(note + "\n", 0), 0u) << text.out;  // the first line of the text output
}

/// A log whose stamps are frozen (every message given one stamp, as MRPT 2.5's carmen2rawlog does) replays into
/// modules that cannot tell time: the replay says so for each module and channel, in its text and its JSON,
/// as `info` and `diagnose` do for the log.
TEST_F(ReplayCli, FrozenStampsAreNamedByTheReplay) {
  {
    auto reader = LogReader::open(log());
    ASSERT_TRUE(reader.ok());
    auto writer = LogWriter::create(file("frozen.lcm"));
    ASSERT_TRUE(writer.ok());
    Event e;
    int64_t first = -1;
    while (reader->next(e) && (first < 0 || e.utime < first + 10000000)) {  // the first 10 s
      if (first < 0) first = e.utime;
      std::vector<uint8_t> bytes(e.data.begin(), e.data.end());
      if (std::string(e.channel) != "GROUND_TRUTH")
        lcmtypes::map_stamps(bytes, e.utime, [&](int64_t) { return first; });
      ASSERT_TRUE(writer->write(e.utime, e.channel, bytes).ok());
    }
    ASSERT_TRUE(writer->close().ok());
  }
  const auto r = driftlab("replay " + file("frozen.lcm") + " --modules slam,estimator --json -o " + file("fr.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  std::map<std::string, std::vector<std::string>> warnings;
  for (const auto& m : j["modules"]) warnings[m["name"]] = m["warnings"].get<std::vector<std::string>>();
  auto frozen = [&](const std::string& module, const std::string& channel) {
    for (const auto& w : warnings[module]) {
      if (w.rfind(channel + ": ", 0) == 0 &&
          w.find("inputs repeat the stamp of the one before (frozen stamps") != std::string::npos) {
        return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(frozen("slam", "SCAN")) << r.out;
  EXPECT_TRUE(frozen("slam", "ODOM")) << r.out;
  EXPECT_TRUE(frozen("estimator", "IMU")) << r.out;
  EXPECT_TRUE(frozen("estimator", "ODOM")) << r.out;
  // The channel whose stamps were left alone is not named.
  for (const auto& [module, list] : warnings) {
    for (const auto& w : list) EXPECT_EQ(w.find("GROUND_TRUTH"), std::string::npos) << w;
  }
  // The text output names them too; the unfrozen session says nothing of the kind.
  const auto text = driftlab("replay " + file("frozen.lcm") + " --modules estimator -o " + file("fr2.lcm"));
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_NE(text.out.find("warning: IMU: "), std::string::npos) << text.out;
  const auto clean = driftlab("replay " + log() + " --modules slam,estimator --end 10 -o " + file("nf.lcm"));
  ASSERT_EQ(clean.code, 0) << clean.err;
  EXPECT_EQ(clean.out.find("frozen"), std::string::npos) << clean.out;
}

TEST_F(ReplayCli, TheSameInputsAndOptionsGiveAByteIdenticalLog) {
  std::ofstream(file("inject.yaml")) << "seed: 9\nstreams:\n  ODOM: {drop_probability: 0.05, jitter_s: 0.01}\n";
  for (const char* out : {"d1.lcm", "d2.lcm"}) {
    const auto r = driftlab("replay " + log() + " --modules slam,estimator,controller --inject " + file("inject.yaml") +
                            " --restamp auto -o " + file(out));
    ASSERT_EQ(r.code, 0) << r.err;
  }
  EXPECT_EQ(test::read_file(file("d1.lcm")), test::read_file(file("d2.lcm")));
}

TEST_F(ReplayCli, InjectedOdometryDropsAreCountedAndListedInTheManifest) {
  std::ofstream(file("drops.yaml")) << "seed: 4\nstreams:\n  ODOM: {burst_enter: 0.02, burst_exit: 0.02}\n";
  const auto r = driftlab("replay " + log() + " --modules estimator --inject " + file("drops.yaml") +
                          " --json -o " + file("dropped.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GT(j["injected_faults"].get<int>(), 0);
  EXPECT_LT(j["channels"]["ODOM"].get<int64_t>(), 2700);  // bursts of about 50 lost messages
  // The manifest is in the output log, where driftlab info lists it.
  const auto info = driftlab("info " + file("dropped.lcm"));
  EXPECT_NE(info.out.find("REPLAY_FAULTS"), std::string::npos);
}

TEST_F(ReplayCli, AModuleWithoutItsInputsWarnsAndStillWritesALog) {
  const auto r = driftlab("replay " + log() + " -c 'SCAN|CAMERA' --modules estimator,controller -o " + file("w.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("warning: estimator: no driftlab.odometry_t on ODOM and no driftlab.pose_t on SLAM_POSE"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("warning: controller: no driftlab.odometry_t or pose_t on ODOM"), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(file("w.lcm")));
  EXPECT_NE(driftlab("info " + file("w.lcm")).out.find("MODULE_STATS"), std::string::npos);
}

// The drone's modules are in the registry: on the ground robot's session (an IMU, but no GNSS, barometer or
// magnetometer) the drone estimator sees the IMU and says what it still lacks, and the flight stack and the offboard
// script, with no estimate to fly on, say so instead of flying.
TEST_F(ReplayCli, TheDroneModulesRunAndSayWhatTheyLackOnAGroundSession) {
  const auto r = driftlab("replay " + log() + " --modules drone_estimator,flight,offboard --json -o " + file("d.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["modules"].size(), 3u);
  EXPECT_EQ(j["modules"][0]["name"], "drone_estimator");
  EXPECT_GT(j["modules"][0]["inputs"].get<int64_t>(), 0);
  EXPECT_NE(j["modules"][0]["warnings"].dump().find("never initialised"), std::string::npos) << r.out;
  EXPECT_EQ(j["modules"][1]["name"], "flight");
  EXPECT_NE(j["modules"][1]["warnings"].dump().find("nothing flown"), std::string::npos) << r.out;
  EXPECT_EQ(j["modules"][2]["name"], "offboard");
  EXPECT_NE(j["modules"][2]["warnings"].dump().find("the mission never started"), std::string::npos) << r.out;
  EXPECT_TRUE(std::filesystem::exists(file("d.lcm")));
}

// match_odometry auto (the default) on 90 s of the default scenario without faults (899 matches): the
// simulator's wheel odometry turns as the module's noise model for it says (90% of the matches within 0.7-0.9 of
// its heading standard deviations; on at 2.2 or less), so the odometry is weighed in, and the trajectory as last
// optimised, the loop records and the map are the ones match_odometry true gives, to the last digit: the weighed
// graph matched every scan from the first. (The poses published while it decided are the other graph's.)
TEST_F(ReplayCli, SlamWeighsInGoodOdometry) {
  std::ofstream(file("no-faults.yaml")) << "streams: {}\n";
  ASSERT_EQ(driftlab("sim --duration 90 --faults " + file("no-faults.yaml") + " -o " + file("clean.lcm")).code, 0);
  const auto r = driftlab("replay " + file("clean.lcm") + " --modules slam --json -o " + file("auto.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& metrics = j["modules"][0]["metrics"];
  EXPECT_GE(metrics["odometry_heading_checks"].get<double>(), 600);
  EXPECT_EQ(metrics["match_odometry_auto"].get<double>(), 1);
  EXPECT_LE(metrics["match_odometry_auto_q90"].get<double>(), 2.2);
  EXPECT_EQ(metrics["scans_weighed"].get<double>(), metrics["odometry_heading_checks"].get<double>());
  std::ofstream(file("on.yaml")) << "slam:\n  2d: {match_odometry: true}\n";
  ASSERT_EQ(
      driftlab("replay " + file("clean.lcm") + " --modules slam --config " + file("on.yaml") + " -o " + file("on.lcm"))
          .code,
      0);
  for (const char* channel : {"SLAM_TRAJECTORY", "SLAM_LOOPS", "SLAM_MAP"}) {
    const auto ours = test::messages_on(file("auto.lcm"), channel);
    EXPECT_FALSE(ours.empty()) << channel;
    EXPECT_TRUE(ours == test::messages_on(file("on.lcm"), channel)) << channel;
  }
  // After the decision the poses published are the ones true gives too.
  const auto published = test::messages_on(file("auto.lcm"), "SLAM_POSE"),
             on = test::messages_on(file("on.lcm"), "SLAM_POSE");
  ASSERT_EQ(published.size(), on.size());
  EXPECT_TRUE(published.back() == on.back());
  EXPECT_FALSE(published[100] == on[100]);
}

TEST_F(ReplayCli, SlamMapsTheSessionAndFeedsTheEstimator) {
  const auto r = driftlab("replay " + log() + " --modules slam,estimator --json -o " + file("slam.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& slam = j["modules"][0];
  EXPECT_EQ(slam["name"], "slam");
  EXPECT_GT(slam["metrics"]["scans"].get<double>(), 550);  // 10 Hz for 60 s, less the injected drops
  EXPECT_TRUE(slam["warnings"].empty()) << slam["warnings"];
  // The simulator's wheel odometry turns as the module's noise model for it says: 90% of the matches within 2.0
  // of its heading standard deviations (a true model: 1.645; ours 0.69), where every benchmark log but the
  // Freiburg clinic is further off (tests/slam/carmen_test.cc), and slam.2d.match_odometry may be weighed in.
  EXPECT_GT(slam["metrics"]["odometry_heading_checks"].get<double>(), 500);
  EXPECT_LE(slam["metrics"]["odometry_heading_q90"].get<double>(), 2.0);
  test::expect_doc_figures("docs/slam.md", "**Which logs it suits: the odometry's heading against the matches.**",
                           "the simulator's default scenario (60 s)", 1,
                           {slam["metrics"]["odometry_heading_q90"].get<double>()});
  // match_odometry auto decides after 600 checks; a session with fewer stays off (SlamWeighsInGoodOdometry).
  EXPECT_LT(slam["metrics"]["odometry_heading_checks"].get<double>(), 600);
  EXPECT_EQ(slam["metrics"]["match_odometry_auto"].get<double>(), 0);
  EXPECT_EQ(slam["metrics"].count("match_odometry_auto_q90"), 0u);
  EXPECT_GT(std::filesystem::file_size(file("slam-map.png")), 1000u);
  EXPECT_TRUE(std::filesystem::exists(file("slam-map.yaml")));
  EXPECT_NE(driftlab("info " + file("slam.lcm")).out.find("SLAM_MAP"), std::string::npos);
  EXPECT_LT(ate(file("slam.lcm") + ":SLAM_POSE"), 0.05);
  EXPECT_LT(ate(file("slam.lcm") + ":EKF_ODOM"), 0.05);
}

TEST_F(ReplayCli, SlamPicksTheBackendTheDataCallsFor) {
  ASSERT_EQ(driftlab("sim " + std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/indoor_3d.yaml --duration 3 -o " +
                     file("p.lcm")).code,
            0);
  // Laser scans and clouds: 2D, unless asked; clouds only: 3D.
  EXPECT_NE(driftlab("replay " + file("p.lcm") + " --modules slam").out.find("slam: 2d backend"), std::string::npos);
  const auto three = driftlab("replay " + file("p.lcm") + " -c 'POINTS|ODOM|TF_STATIC' --modules slam -o " +
                              file("p3.lcm"));
  ASSERT_EQ(three.code, 0) << three.err;
  EXPECT_NE(three.out.find("slam: 3d backend"), std::string::npos) << three.out;
  EXPECT_NE(three.out.find("clouds 30"), std::string::npos) << three.out;
  EXPECT_TRUE(std::filesystem::exists(file("p3-map.pcd")));
  // The backend and the inputs are chosen from what the modules receive after --remap: clouds delivered on the 2D
  // scan channel's name make a 3D session that takes them there, and scans remapped away from it are found by
  // their type. (Before, the check looked the remapped names up in the raw logs and chose 2D.)
  const auto clouds = driftlab("replay " + file("p.lcm") + " -c 'POINTS|ODOM|TF_STATIC' --remap POINTS=SCAN " +
                               "--modules slam -o " + file("p4.lcm"));
  ASSERT_EQ(clouds.code, 0) << clouds.err;
  EXPECT_NE(clouds.out.find("slam: 3d backend"), std::string::npos) << clouds.out;
  EXPECT_NE(clouds.out.find("slam: clouds from SCAN (driftlab.point_cloud_t; none on POINTS)"), std::string::npos)
      << clouds.out;
  EXPECT_NE(clouds.out.find("clouds 30"), std::string::npos) << clouds.out;
  const auto renamed =
      driftlab("replay " + file("p.lcm") + " --remap SCAN=OLD_SCAN --modules slam -o " + file("p5.lcm"));
  ASSERT_EQ(renamed.code, 0) << renamed.err;
  EXPECT_NE(renamed.out.find("slam: 2d backend"), std::string::npos) << renamed.out;
  EXPECT_NE(renamed.out.find("slam: scans from OLD_SCAN (driftlab.laser_scan_t; none on SCAN)"), std::string::npos)
      << renamed.out;
}

TEST_F(ReplayCli, MrptRawlogsComeInAndGoOut) {
  const std::string sena = "'/usr/share/mrpt/datasets/2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog'";
  const auto in = driftlab("import rawlog " + sena + " -o " + file("sena.lcm"));
  ASSERT_EQ(in.code, 0) << in.err;
  EXPECT_NE(in.out.find("SCAN                         225"), std::string::npos) << in.out;
  const auto replay = driftlab("replay " + file("sena.lcm") + " --modules slam --json -o " + file("sena_slam.lcm"));
  ASSERT_EQ(replay.code, 0) << replay.err;
  // A pose per scan as it went, the trajectory as last optimised (a pose per scan again), the map, and a record
  // of each loop test (one each, more for those that waited for a second match or were undone).
  const auto module = nlohmann::json::parse(replay.out)["modules"][0];
  int64_t loop_records = 0;
  for (const auto& e : test::read_all(file("sena_slam.lcm"))) loop_records += e.channel == "SLAM_LOOPS";
  EXPECT_GE(loop_records, module["metrics"]["loop_tests"].get<int64_t>());
  EXPECT_GT(module["metrics"]["loop_tests"].get<int64_t>(), 0);
  EXPECT_EQ(module["outputs"].get<int64_t>(), 224 + 224 + 1 + loop_records);
  const auto out = driftlab("export rawlog " + log() + " -o " + file("session.rawlog"));
  ASSERT_EQ(out.code, 0) << out.err;
  EXPECT_NE(out.out.find("CObservation2DRangeScan"), std::string::npos);
  const auto missing = driftlab("import rawlog " + file("none.rawlog") + " -o " + file("none.lcm"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_EQ(missing.err, "driftlab: " + file("none.rawlog") + ": no such rawlog file\n");
}

TEST_F(ReplayCli, BadInputGetsOneLineAndExitCode2) {
  struct Case {
    std::string args, message;
  };
  std::ofstream(file("bad_key.yaml")) << "estimator:\n  window_s: 0.2\n  gyro_nosie: 0.01\n";
  std::ofstream(file("bad_module.yaml")) << "slamm: {}\n";
  std::ofstream(file("bad_restamp.yaml")) << "channels: [IMU]\n";
  std::ofstream(file("bad_slam.yaml")) << "slam:\n  2d:\n    icp_iterations: 3\n";
  std::ofstream(file("bad_backend.yaml")) << "slam:\n  backend: lidar\n";
  std::ofstream(file("bad_scenario.yaml")) << "controller:\n  scenario: [a, b]\n";
  std::ofstream(file("bad_module_key.yaml")) << "? [slam]\n: {}\n";
  // Rates that used to loop forever (estimator) or abort (controller: a timer period of 0 us).
  std::ofstream(file("huge_rate.yaml")) << "estimator: {publish_rate: 1e7}\n";
  // The drone's modules read their maps through the same tables: a misspelt or out-of-range key names file and line.
  std::ofstream(file("bad_flight.yaml")) << "flight:\n  vehicle:\n    mas: 1.2\n";
  std::ofstream(file("bad_offboard.yaml")) << "offboard:\n  stream_rate: 0\n";
  std::ofstream(file("bad_drone_estimator.yaml")) << "drone_estimator:\n  window_s: 0.3\n  max_age: 1\n";
  std::ofstream(file("huge_controller_rate.yaml")) << "controller:\n  route: [[0, 0], [1, 0]]\n  rate: 1e308\n";
  const std::vector<Case> cases = {
      {"--modules estimater",
       "--modules: unknown module 'estimater' (known: slam, estimator, controller, drone_estimator, flight, offboard)"},
      {"--modules estimator --config " + file("bad_key.yaml"),
       file("bad_key.yaml") + ":3: unknown key 'estimator.gyro_nosie'"},
      {"--modules estimator --config " + file("bad_module.yaml"),
       file("bad_module.yaml") + ":1: unknown module 'slamm'"},
      {"--modules slam --config " + file("bad_slam.yaml"),
       file("bad_slam.yaml") + ":3: unknown key 'slam.2d.icp_iterations'"},
      {"--modules slam --config " + file("bad_backend.yaml"),
       file("bad_backend.yaml") + ":2: slam.backend = lidar must be auto, 2d or 3d"},
      // Non-scalar values where a name is expected: one line, not std::terminate (YAML::BadConversion).
      {"--modules controller --config " + file("bad_scenario.yaml"),
       file("bad_scenario.yaml") + ":2: controller.scenario: expected a file name"},
      {"--modules slam --config " + file("bad_module_key.yaml"),
       file("bad_module_key.yaml") + ":1: expected a module name"},
      {"--modules estimator --config " + file("huge_rate.yaml"),
       file("huge_rate.yaml") + ":1: estimator.publish_rate = 1e+07 is outside 0.1..1000 Hz"},
      {"--modules controller --config " + file("huge_controller_rate.yaml"),
       file("huge_controller_rate.yaml") + ":3: controller.rate = 1e+308 is outside 0.1..1000 Hz"},
      {"--modules flight --config " + file("bad_flight.yaml"),
       file("bad_flight.yaml") + ":3: unknown key 'flight.vehicle.mas'"},
      {"--modules offboard --config " + file("bad_offboard.yaml"),
       file("bad_offboard.yaml") + ":2: offboard.stream_rate = 0 is outside"},
      {"--modules drone_estimator --config " + file("bad_drone_estimator.yaml"),
       file("bad_drone_estimator.yaml") + ":3: unknown key 'drone_estimator.max_age'"},
      {"--restamp " + file("bad_restamp.yaml"),
       file("bad_restamp.yaml") + ":1: channels must be a map of CHANNEL: {offset_s, drift_ppm, reference_utime}"},
      {"--restamp " + file("missing.yaml"), file("missing.yaml") + ": cannot open"},
      {"--remap SCAN", "--remap SCAN: expected FROM=TO"},
      {"-c '(' --modules slam", "invalid channel regex '('"},
      {"--inject " + file("bad_key.yaml"), file("bad_key.yaml") + ":1:"},
  };
  for (const auto& c : cases) {
    const auto r = driftlab("replay " + log() + " " + c.args + " -o " + file("bad.lcm"));
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("driftlab: " + c.message, 0), 0u) << c.args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(file("bad.lcm"))) << c.args;
  }
  const auto missing = driftlab("replay " + file("nope.lcm"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_EQ(missing.err, "driftlab: " + file("nope.lcm") + ": cannot open: No such file or directory\n");
}

}  // namespace
}  // namespace driftlab
