// The arm end to end through the commands a user runs, on the simulator's manipulator scenarios (issue 17):
// `driftlab eval --arm` (joint and end-effector tracking error against ground truth, the joint limits, the
// oscillation), `driftlab diagnose` on the `map -> odom` transform against the odometry it is composed with, and
// `driftlab report` plotting commanded against measured joint motion with the measured delay. Each simulated log is
// made once per test process, when a test first needs it.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/log_writer.h"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_result_t.hpp"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/robot_description_t.hpp"
#include "kinematics/arm_chain.h"
#include "tests/doc_figures.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using test::decode;

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kScenarios = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/";
constexpr double kPi = 3.14159265358979323846;

test::CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

/// The log of `seconds` of a shipped scenario, simulated on first use in this process.
const std::string& simulated(const std::string& scenario, double seconds) {
  static test::TempDir dir;
  static std::map<std::string, std::string> logs;
  const std::string key = scenario + "-" + std::to_string(static_cast<int>(seconds));
  auto it = logs.find(key);
  if (it == logs.end()) {
    const std::string out = dir.file(key + ".lcm");
    const auto r =
        driftlab("sim " + kScenarios + scenario + ".yaml --duration " + std::to_string(seconds) + " -o " + out);
    EXPECT_EQ(r.code, 0) << r.err;
    it = logs.emplace(key, out).first;
  }
  return it->second;
}

nlohmann::json eval_arm(const std::string& log, const std::string& options = "") {
  const auto r = driftlab("eval --arm " + log + " " + options + " --json");
  EXPECT_EQ(r.code, 0) << r.err;
  return nlohmann::json::parse(r.out.empty() ? "{}" : r.out)["arm"];
}

Eigen::Isometry3d pose_of(const driftlab::pose_t& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  t.linear() = Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
                   .normalized()
                   .toRotationMatrix();
  return t;
}

// The bar on the clean scenario, over the whole 60 s run (four pick-and-place cycles) against ground truth:
// the end effector within 1 cm and 1 degree of where the commanded joints put it, every joint within its limits.
TEST(ArmEval, CleanRunTracksThePlanWithin1cmAnd1DegreeAndKeepsTheLimits) {
  const std::string& log = simulated("manipulator", 60);
  const auto a = eval_arm(log);
  ASSERT_TRUE(a.is_object());
  EXPECT_EQ(a["reference"], "commanded");
  EXPECT_EQ(a["channels"]["commands"], "ARM_CMD");
  EXPECT_EQ(a["channels"]["joint_states"], "JOINT_STATES");
  EXPECT_EQ(a["channels"]["ee_truth"], "EE_TRUTH");
  EXPECT_EQ(a["channels"]["base_truth"], "GROUND_TRUTH");
  EXPECT_EQ(a["commands"], 1201);
  EXPECT_LT(a["span_s"][0].get<double>(), 0.01);  // the whole run
  EXPECT_GT(a["span_s"][1].get<double>(), 59.99);
  const auto& ee = a["ee"];
  ASSERT_TRUE(ee.is_object()) << a["ee_problem"];
  EXPECT_EQ(ee["base_link"], "base_link");
  EXPECT_EQ(ee["tip_link"], "panda_hand_tcp");
  EXPECT_GT(ee["position_m"]["rmse"].get<double>(), 1e-4);  // the physics is not the model: not zero
  EXPECT_LT(ee["position_m"]["max"].get<double>(), 0.01);
  EXPECT_LT(ee["rotation_deg"]["max"].get<double>(), 1.0);
  ASSERT_EQ(a["joints"].size(), 7u);
  for (size_t j = 0; j < 7; ++j) {
    const auto& joint = a["joints"][j];
    SCOPED_TRACE(joint["name"].get<std::string>());
    EXPECT_EQ(joint["name"], "panda_joint" + std::to_string(j + 1));
    EXPECT_LT(joint["error_rad"]["max"].get<double>(), 0.5 * kPi / 180);
    ASSERT_TRUE(joint["limits"].is_object());
    EXPECT_EQ(joint["beyond"]["position"], 0);
    EXPECT_EQ(joint["beyond"]["velocity"], 0);
    EXPECT_GT(joint["reached"]["min"].get<double>(), joint["limits"]["lower"].get<double>());
    EXPECT_LT(joint["reached"]["max"].get<double>(), joint["limits"]["upper"].get<double>());
    EXPECT_GT(joint["reached"]["max_speed"].get<double>(), 0.1);  // it moved
    EXPECT_LT(joint["reached"]["max_speed"].get<double>(), joint["limits"]["velocity"].get<double>());
  }
  std::printf("clean: EE %.2f mm RMS, %.2f mm max, %.3f deg max; oscillation %.3f mm at %.1f Hz\n",
              ee["position_m"]["rmse"].get<double>() * 1e3, ee["position_m"]["max"].get<double>() * 1e3,
              ee["rotation_deg"]["max"].get<double>(), ee["oscillation"]["rms_m"].get<double>() * 1e3,
              ee["oscillation"]["peak_hz"].get<double>());
}

// The base drives while the arm moves (manipulator_mobile: the 6 m corridor at 0.3 m/s, then holding, while the arm
// plays the clean scenario's pick-and-place). 22 s: the drive (20 s at speed, the ramps) and one and a half cycles of
// the arm, short enough for the sanitizer build. Before the base's casters were sprung (sim/robot.cc) the wheels
// carried almost none of the weight and the base slid on its casters under the arm's reaction: 47 degrees of yaw in
// 4 s, 7.1 m from where its wheel odometry put it after 22 s.
TEST(ArmEval, MobileRunReachesTheGoalWithItsOdometryAndTheArmTracksOnTheMovingBase) {
  const std::string& log = simulated("manipulator_mobile", 22);
  std::map<int64_t, Eigen::Isometry3d> truth, odom;
  for (const auto& e : test::read_all(log)) {
    if (e.channel == "GROUND_TRUTH") {
      const auto p = decode<driftlab::pose_t>(e);
      truth[p.header.utime] = pose_of(p);
    } else if (e.channel == "ODOM") {
      const auto o = decode<driftlab::odometry_t>(e);
      Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
      t.translation() = Eigen::Vector3d(o.position.x, o.position.y, o.position.z);
      t.linear() = Eigen::Quaterniond(o.orientation.w, o.orientation.x, o.orientation.y, o.orientation.z)
                       .normalized()
                       .toRotationMatrix();
      odom[o.header.utime] = t;
    }
  }
  ASSERT_GT(truth.size(), 2000u);
  ASSERT_GT(odom.size(), 1000u);
  // The odometry against the truth, both from their first common stamp, at every common stamp (ODOM's 50 Hz steps
  // are among the truth's 100 Hz ones).
  const Eigen::Isometry3d truth0 = truth.at(odom.begin()->first), odom0 = odom.begin()->second;
  double travelled = 0, worst_m = 0, worst_heading = 0, veer = 0;
  Eigen::Vector3d last = truth0.translation();
  for (const auto& [utime, o] : odom) {
    const auto t = truth.find(utime);
    ASSERT_NE(t, truth.end()) << utime;
    travelled += (t->second.translation() - last).head<2>().norm();
    last = t->second.translation();
    const Eigen::Isometry3d rel_truth = truth0.inverse() * t->second, rel_odom = odom0.inverse() * o;
    worst_m = std::max(worst_m, (rel_truth.translation() - rel_odom.translation()).head<2>().norm());
    const Eigen::Matrix3d d = rel_truth.linear().transpose() * rel_odom.linear();
    worst_heading = std::max(worst_heading, std::abs(std::atan2(d(1, 0), d(0, 0))));
    veer = std::max(veer, std::abs(std::atan2(t->second.linear()(1, 0), t->second.linear()(0, 0))));
  }
  // The route's goal is (9, 6), reached after 20 s at speed; 0.3 m is half the base's width across its wheels.
  const Eigen::Vector3d end = truth.rbegin()->second.translation();
  EXPECT_LT((end.head<2>() - Eigen::Vector2d(9, 6)).norm(), 0.3);
  EXPECT_GT(travelled, 5.7);
  // Wheel odometry on a hard floor drifts by slip and errors of the wheels' geometry, commonly a percent or two of
  // the distance. This scenario's encoders have no calibration error, so only slip is left: 2 % is the bar of a base
  // whose wheels hold the floor (the sliding one was 120 % off).
  EXPECT_LT(worst_m, 0.02 * travelled);
  // Nor does the heading slip away from the odometry's, or from the corridor's (east): one degree, where the sliding
  // base veered thirty.
  EXPECT_LT(worst_heading, kPi / 180);
  EXPECT_LT(veer, kPi / 180);
  // The hand on the moving base: eval compares it in base_link (GROUND_TRUTH, the arm's base's truth), to which the
  // commander's panda_link0 is fixed, so the plan is the clean scenario's and so is the bar (1 cm and 1 degree; the
  // base's accelerations and the casters' springing are what the arm has to hold against).
  const auto a = eval_arm(log);
  ASSERT_TRUE(a["ee"].is_object()) << a["ee_problem"];
  EXPECT_EQ(a["channels"]["base_truth"], "GROUND_TRUTH");
  EXPECT_EQ(a["ee"]["base_link"], "base_link");
  EXPECT_GT(a["commands"].get<int>(), 430);  // the arm was commanded all the way (20 Hz)
  EXPECT_LT(a["ee"]["position_m"]["max"].get<double>(), 0.01);
  EXPECT_LT(a["ee"]["rotation_deg"]["max"].get<double>(), 1.0);
  std::printf(
      "mobile: %.2f m travelled, odometry %.3f m and %.3f deg off at worst, heading %.3f deg at worst, end "
      "(%.3f, %.3f); EE %.2f mm max, %.3f deg max\n",
      travelled, worst_m, worst_heading * 180 / kPi, veer * 180 / kPi, end.x(), end.y(),
      a["ee"]["position_m"]["max"].get<double>() * 1e3, a["ee"]["rotation_deg"]["max"].get<double>());
  // The simulator's page and the arm tutorial say these figures (the run's 22 s and the route's 6 m are settings).
  const double ee_mm = a["ee"]["position_m"]["max"].get<double>() * 1e3;
  const double ee_deg = a["ee"]["rotation_deg"]["max"].get<double>();
  test::expect_doc_text_figures("docs/simulator.md", "The base ends at (", " degree of the commanded plan",
                                {end.x(), end.y(), NAN, worst_m, worst_heading * 180 / kPi, NAN, ee_mm, ee_deg});
  test::expect_doc_text_figures("docs/tutorial-why-does-my-arm-oscillate.md",
                                "so the base's motion is not counted as the arm's error: ", "° at most over the first",
                                {ee_mm, ee_deg});
  test::expect_doc_text_figures("docs/tutorial-why-does-my-arm-oscillate.md", "and the odometry stays within ",
                                " m of the truth over the", {worst_m});
}

// Against the controller's desired state, eval's numbers are what the URDF's FK of ARM_STATE's desired joints gives
// against the ground truth, computed here on its own from the log (the stamps coincide, so nothing is interpolated).
TEST(ArmEval, DesiredReferenceEqualsFkOfTheControllerStateAgainstGroundTruth) {
  const std::string& log = simulated("manipulator", 20);
  const auto a = eval_arm(log, "--arm-reference desired");
  ASSERT_TRUE(a["ee"].is_object()) << a["ee_problem"];
  EXPECT_EQ(a["channels"]["controller_state"], "ARM_STATE");
  const auto events = test::read_all(log);
  std::map<int64_t, Eigen::Isometry3d> base, ee;
  std::map<int64_t, std::vector<double>> measured;
  std::unique_ptr<kinematics::ArmChain> chain;
  for (const auto& e : events) {
    if (e.channel == "GROUND_TRUTH")
      base[decode<driftlab::pose_t>(e).header.utime] = pose_of(decode<driftlab::pose_t>(e));
    if (e.channel == "EE_TRUTH") ee[decode<driftlab::pose_t>(e).header.utime] = pose_of(decode<driftlab::pose_t>(e));
    if (e.channel == "JOINT_STATES") {
      const auto s = decode<driftlab::joint_state_t>(e);
      measured[s.header.utime] = std::vector<double>(s.position.begin() + 2, s.position.end());  // after the wheels
      ASSERT_EQ(s.name[2], "panda_joint1");
    }
    if (e.channel == "ROBOT_DESCRIPTION") {
      auto model = kinematics::RobotModel::parse(decode<driftlab::robot_description_t>(e).urdf, "log");
      ASSERT_TRUE(model.ok()) << model.error().message;
      auto c = kinematics::ArmChain::create(*model, "base_link", "panda_hand_tcp", true);
      ASSERT_TRUE(c.ok()) << c.error().message;
      chain = std::make_unique<kinematics::ArmChain>(std::move(*c));
    }
  }
  ASSERT_NE(chain, nullptr);
  double max_m = 0, max_rad = 0, sum_sq = 0;
  std::vector<double> joint_max(7, 0.0);
  int n = 0;
  for (const auto& e : events) {
    if (e.channel != "ARM_STATE") continue;
    const auto s = decode<driftlab::joint_trajectory_state_t>(e);
    const auto b = base.find(s.header.utime), t = ee.find(s.header.utime);
    const auto q = measured.find(s.header.utime);
    ASSERT_TRUE(b != base.end() && t != ee.end() && q != measured.end()) << s.header.utime;
    const Eigen::Isometry3d want = chain->fk(Eigen::Map<const Eigen::VectorXd>(s.desired_positions.data(), 7));
    const Eigen::Isometry3d got = b->second.inverse() * t->second;
    const double d = kinematics::position_distance(want, got);
    max_m = std::max(max_m, d);
    sum_sq += d * d;
    max_rad = std::max(max_rad, kinematics::angle_distance(want, got));
    for (size_t j = 0; j < 7; ++j)
      joint_max[j] = std::max(joint_max[j], std::abs(q->second[j] - s.desired_positions[j]));
    ++n;
  }
  EXPECT_EQ(a["ee"]["position_m"]["rmse"].is_number(), true);
  EXPECT_EQ(n, 2001);
  EXPECT_NEAR(a["ee"]["position_m"]["max"].get<double>(), max_m, 1e-12);
  EXPECT_NEAR(a["ee"]["position_m"]["rmse"].get<double>(), std::sqrt(sum_sq / n), 1e-12);
  EXPECT_NEAR(a["ee"]["rotation_deg"]["max"].get<double>(), max_rad * 180 / kPi, 1e-9);
  for (size_t j = 0; j < 7; ++j) EXPECT_NEAR(a["joints"][j]["error_rad"]["max"].get<double>(), joint_max[j], 1e-12);
  EXPECT_LT(max_m, 0.01);  // the bar against what the controller wants, too
  EXPECT_LT(max_rad, kPi / 180);
}

// The latency scenario: every command 120 ms late. Against the commanded plans the hand lags by centimetres where
// the clean run's is millimetres; against the controller's own desired state both are the same (the controller
// tracks what it gets: the commands are late), and the hand shakes at the command rate, which the clean one does not.
TEST(ArmEval, LatencyRunLagsTheCommandsAndShakesAtTheCommandRate) {
  // Two pick-and-place cycles of each (the sanitizer build runs these too).
  const auto clean = eval_arm(simulated("manipulator", 28));
  const auto late = eval_arm(simulated("manipulator_latency", 28));
  ASSERT_TRUE(clean["ee"].is_object() && late["ee"].is_object());
  const double clean_rms = clean["ee"]["position_m"]["rmse"].get<double>();
  const double late_rms = late["ee"]["position_m"]["rmse"].get<double>();
  EXPECT_GT(late_rms, 10 * clean_rms);
  EXPECT_GT(late["ee"]["position_m"]["max"].get<double>(), 0.03);
  for (size_t j = 0; j < 7; ++j) {
    EXPECT_GT(late["joints"][j]["error_rad"]["rmse"].get<double>(),
              5 * clean["joints"][j]["error_rad"]["rmse"].get<double>())
        << j;
  }
  const auto clean_desired = eval_arm(simulated("manipulator", 28), "--arm-reference desired");
  const auto late_desired = eval_arm(simulated("manipulator_latency", 28), "--arm-reference desired");
  EXPECT_NEAR(late_desired["ee"]["position_m"]["rmse"].get<double>(),
              clean_desired["ee"]["position_m"]["rmse"].get<double>(),
              0.2 * clean_desired["ee"]["position_m"]["rmse"].get<double>());
  // The oscillation: the hand's motion above 5 Hz, where the plan has next to nothing.
  const auto& shake = late["ee"]["oscillation"];
  const auto& calm = clean["ee"]["oscillation"];
  EXPECT_EQ(shake["cutoff_hz"].get<double>(), 5.0);
  EXPECT_GT(shake["rms_m"].get<double>(), 4 * calm["rms_m"].get<double>());
  const auto d = driftlab("diagnose " + simulated("manipulator_latency", 28) + " --json");
  ASSERT_EQ(d.code, 0) << d.err;
  const double period = nlohmann::json::parse(d.out)["command_loops"][0]["command_period_s"].get<double>();
  EXPECT_NEAR(shake["peak_hz"].get<double>(), 1 / period, 1.0);  // 20 Hz: each late command re-plans the arm
  EXPECT_EQ(late_desired["ee"]["oscillation"], shake);           // a property of the motion, whatever the reference
  std::printf("latency: EE %.2f mm RMS (clean %.2f), oscillation %.3f mm at %.1f Hz (clean %.3f mm)\n", late_rms * 1e3,
              clean_rms * 1e3, shake["rms_m"].get<double>() * 1e3, shake["peak_hz"].get<double>(),
              calm["rms_m"].get<double>() * 1e3);
}

// The fix, shown: `driftlab replay --closed-loop --retime auto` runs the latency scenario again with each command
// starting when it arrived less the delay diagnose measured (120.8 ms), on a controller that honours stamps (as
// ros2_control's does with a stamped trajectory): the hand tracks the commanded plan within 20% of the clean run
// (the bar) and the 20 Hz shake is gone. The log keeps the commander's own stamps, so eval measures against
// the plan as commanded, not as re-timed.
TEST(ArmClosedLoop, RetimedByTheMeasuredDelayTheLateArmTracksAsTheCleanOne) {
  static test::TempDir out;
  const std::string fixed = out.file("late-retimed.lcm");
  const auto r =
      driftlab("replay " + simulated("manipulator_latency", 28) + " --closed-loop --retime auto -o " + fixed);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("retime ARM_CMD: each command starts 120."), std::string::npos) << r.out;
  const auto clean = eval_arm(simulated("manipulator", 28));
  const auto late = eval_arm(simulated("manipulator_latency", 28));
  const auto retimed = eval_arm(fixed);
  ASSERT_TRUE(clean["ee"].is_object() && retimed["ee"].is_object());
  const double clean_rms = clean["ee"]["position_m"]["rmse"].get<double>();
  const double retimed_rms = retimed["ee"]["position_m"]["rmse"].get<double>();
  EXPECT_LT(retimed_rms, 1.2 * clean_rms);
  EXPECT_LT(retimed["ee"]["oscillation"]["rms_m"].get<double>(),
            1.2 * clean["ee"]["oscillation"]["rms_m"].get<double>());
  EXPECT_LT(retimed_rms, 0.2 * late["ee"]["position_m"]["rmse"].get<double>());
  std::printf("retimed: EE %.2f mm RMS (clean %.2f, late %.2f)\n", retimed_rms * 1e3, clean_rms * 1e3,
              late["ee"]["position_m"]["rmse"].get<double>() * 1e3);
}

// The drifting commander's clock (manipulator_clock: -2%, every command after 25 s stale to a stamp-honouring
// controller): diagnose finds the drift, and the closed-loop replay with --restamp auto corrects the commands'
// stamps as the controller receives them: none is refused as stale.
TEST(ArmClosedLoop, RestampedTheDriftingCommandersCommandsAreNoLongerStale) {
  static test::TempDir out;
  const std::string& log = simulated("manipulator_clock", 40);
  const std::string fixed = out.file("clock-restamped.lcm");
  const auto r = driftlab("replay " + log + " --closed-loop --restamp auto -o " + fixed);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("restamp ARM_CMD:"), std::string::npos) << r.out;
  auto stale = [](const std::string& path) {
    int n = 0;
    for (const auto& e : test::read_all(path)) {
      if (e.channel == "ARM_RESULT") n += decode<driftlab::joint_trajectory_result_t>(e).status == "stale";
    }
    return n;
  };
  const int stale_as_logged = stale(log);
  EXPECT_GT(stale_as_logged, 100);
  EXPECT_EQ(stale(fixed), 0);
  test::expect_doc_text_figures("docs/tutorial-why-does-my-arm-oscillate.md", "as stale, where it rejected ",
                                " (tests/apps/arm_test.cc", {static_cast<double>(stale_as_logged)});
}

TEST(ArmEval, BadInputIsOneLineAndExitCode2) {
  const std::string sample = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  for (const auto& [args, words] : std::vector<std::pair<std::string, std::string>>{
           {"--arm " + sample, "no joint trajectory commands"},
           {"--arm /nonexistent.lcm", "/nonexistent.lcm"},
           {"--arm " + sample + " --gt " + sample + ":GROUND_TRUTH", "give it without --gt"},
           {"--arm " + simulated("manipulator", 5) + " --arm-ee NOPE", "--arm-ee NOPE is not a channel of poses"},
           {"--arm " + simulated("manipulator", 5) + " --arm-command EE_TRUTH", "not a channel of joint trajectories"},
       }) {
    const auto r = driftlab("eval " + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(words), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

// A log whose robot description nests 200,000 elements (issue 31): the XML parser recursed once per level and
// crashed `eval --arm`. The URDF in a log goes through the depth scan a URDF file does (kinematics::RobotModel::parse):
// one line naming the log, the channel and the line, exit 2, the JSON named by --json left as it was.
TEST(ArmEval, ALogCarryingAUrdfNested200kDeepIsRefusedInOneLine) {
  test::TempDir dir;
  std::string deep = "<robot name=\"deep\">\n";
  constexpr int kLevels = 200'000;
  deep.reserve(size_t{13} * kLevels);
  for (int i = 0; i < kLevels; ++i) deep += "<link>";
  for (int i = 0; i < kLevels; ++i) deep += "</link>";
  deep += "\n</robot>\n";
  const std::string log = dir.file("deep.lcm");
  {
    auto w = LogWriter::create(log);
    ASSERT_TRUE(w.ok());
    int descriptions = 0;
    for (auto e : test::read_all(simulated("manipulator", 5))) {
      if (e.channel == "ROBOT_DESCRIPTION") {
        auto d = decode<driftlab::robot_description_t>(e);
        d.urdf = deep;
        e.data = test::encode(d);
        ++descriptions;
      }
      ASSERT_TRUE(w->write(e.utime, e.channel, e.data).ok());
    }
    ASSERT_EQ(descriptions, 1);
    ASSERT_TRUE(w->close().ok());
  }
  const std::string json = dir.file("arm.json");
  test::write_file(json, {'{', '}', '\n'});
  const std::string peak = dir.file("peak");
  const auto start = std::chrono::steady_clock::now();
  const auto r = test::run_capture("/usr/bin/time -f %M -o " + peak + " timeout 60 " + kDriftlab + " eval --arm " +
                                   log + " --json-out " + json);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(log + ":ROBOT_DESCRIPTION:2: XML elements nested more than 1000 deep"), std::string::npos)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(test::read_file(json), (std::vector<uint8_t>{'{', '}', '\n'}));
  // The scan is linear and holds nothing per level: eval reads the 5 s log and the 2.6 MB URDF. It peaks at
  // 15 MiB in 0.12 s (release), 48 MiB in 0.4 s under ASan; 500 MiB is well below the bound of 1 GB and
  // far above both. 30 s is the bound, for the slowest (sanitized, loaded) runner.
  std::ifstream in(peak);  // "Command exited with non-zero status 2", then the peak [KiB]
  long kib = 0;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && std::isdigit(static_cast<unsigned char>(line[0]))) kib = std::stol(line);
  }
  std::printf("eval --arm on a URDF nested 200k deep: %.2f s, peak %ld MiB\n", seconds, kib / 1024);
  EXPECT_GT(kib, 0);
  EXPECT_LT(kib / 1024, 500) << "MiB";
  EXPECT_LT(seconds, 30);
}

/// The stamp check of `transform` against `channel` in a diagnosis.
nlohmann::json tf_check(const nlohmann::json& diagnosis, const std::string& transform, const std::string& channel) {
  for (const auto& c : diagnosis["tf"]["stamps"]) {
    if (c["transform"] == transform && c["channel"] == channel) return c;
  }
  ADD_FAILURE() << "no check of " << transform << " against " << channel;
  return {};
}

// The issue's `map -> odom` stamped differently from `/odom`: the localization's clock 250 ms behind (the replayer's
// fault injection) makes every lookup at an odometry stamp extrapolate; the clean run's 10 Hz map -> odom against
// 50 Hz odometry is waited for within its period and is no problem.
TEST(ArmTf, MapToOdomStampedBehindTheOdometryIsMeasuredAndNamed) {
  const std::string& log = simulated("manipulator", 20);
  const auto clean = driftlab("diagnose " + log + " --json");
  ASSERT_EQ(clean.code, 0) << clean.err;
  const auto c = nlohmann::json::parse(clean.out);
  for (const auto& p : c["tf"]["problems"]) {
    EXPECT_EQ(p.get<std::string>().find("extrapolation"), std::string::npos) << p;
    EXPECT_EQ(p.get<std::string>().find("behind"), std::string::npos) << p;
  }
  const auto odom = tf_check(c, "map -> odom", "ODOM");
  EXPECT_EQ(odom["tf_channel"], "TF_MAP");
  EXPECT_EQ(odom["frame"], "odom");
  EXPECT_NEAR(odom["period_s"].get<double>(), 0.1, 1e-9);
  EXPECT_LT(std::abs(odom["offset_s"].get<double>()), 0.021);  // within an odometry period
  EXPECT_LT(odom["lead_s"]["max"].get<double>(), 0.1);

  test::TempDir dir;
  const std::string faults = std::string(DRIFTLAB_SOURCE_DIR) + "/docs/examples/tf-map-behind.yaml";
  const auto replay = driftlab("replay " + log + " --inject " + faults + " -o " + dir.file("behind.lcm"));
  ASSERT_EQ(replay.code, 0) << replay.err;
  const auto bad = driftlab("diagnose " + dir.file("behind.lcm") + " --json");
  ASSERT_EQ(bad.code, 0) << bad.err;
  const auto b = nlohmann::json::parse(bad.out);
  const auto behind = tf_check(b, "map -> odom", "ODOM");
  EXPECT_NEAR(behind["offset_s"].get<double>() - odom["offset_s"].get<double>(), 0.25, 1e-6);
  EXPECT_NEAR(behind["tf_latency_s"].get<double>(), 0.25, 1e-6);
  EXPECT_NEAR(behind["data_latency_s"].get<double>(), 0.0, 1e-6);
  EXPECT_GT(behind["wait_s"]["p50"].get<double>(), 0.25);
  int found = 0;
  for (const auto& p : b["tf"]["problems"]) {
    const std::string text = p;
    if (text.find("transform 'map' -> 'odom' (TF_MAP) is 250.0 ms behind ODOM") == std::string::npos) continue;
    ++found;
    EXPECT_NE(text.find("extrapolation into the future"), std::string::npos) << text;
    EXPECT_NE(text.find("TF_MAP's stamps are 250.0 ms older than their arrival, ODOM's 0.0 ms"), std::string::npos)
        << text;
  }
  EXPECT_EQ(found, 1) << b["tf"]["problems"].dump(1);
  // The text names it too.
  const auto text = driftlab("diagnose " + dir.file("behind.lcm"));
  EXPECT_NE(text.out.find("'map' -> 'odom' (TF_MAP, every 100 ms) with ODOM: 250.0 ms behind it"), std::string::npos)
      << text.out;
}

// driftlab report on the latency run: commanded and measured joint motion with the 120 ms diagnose measures, and the
// arm's tracking error tabulated from eval's JSON.
TEST(ArmReport, PlotsCommandedAgainstMeasuredJointMotionWithTheMeasuredDelay) {
  const std::string& log = simulated("manipulator_latency", 20);
  test::TempDir dir;
  ASSERT_EQ(driftlab("eval --arm " + log + " --json-out " + dir.file("arm.json")).code, 0);
  const auto r = driftlab("report " + log + " --eval " + dir.file("arm.json") + " -o " + dir.file("report"));
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream in(dir.file("report/report.json"));
  const auto data = nlohmann::json::parse(in);
  ASSERT_EQ(data["arms"].size(), 1u);
  const auto& arm = data["arms"][0];
  EXPECT_EQ(arm["command_channel"], "ARM_CMD");
  EXPECT_EQ(arm["state_channel"], "JOINT_STATES");
  ASSERT_EQ(arm["joints"].size(), 7u);
  EXPECT_NEAR(arm["delay_s"].get<double>(), 0.120, 0.005);
  EXPECT_FALSE(arm["curve"].empty());
  ASSERT_EQ(arm["commanded"].size(), 7u);
  const size_t n = arm["t"].size();
  EXPECT_GT(n, 1900u);  // the joint states at 100 Hz
  // The measured joints repeat the commanded ones one delay later (here: within 12 ms of 120, on the samples).
  const auto& cmd = arm["commanded"][1];
  const auto& meas = arm["measured"][1];
  double best = 1e9;
  int best_lag = 0;
  for (int lag = 0; lag <= 30; ++lag) {  // in 10 ms samples
    double sum = 0;
    for (size_t i = 0; i + static_cast<size_t>(lag) < n; ++i) {
      const double d = meas[i + static_cast<size_t>(lag)].get<double>() - cmd[i].get<double>();
      sum += d * d;
    }
    if (sum < best) best = sum, best_lag = lag;
  }
  EXPECT_NEAR(best_lag * 10, 120, 12);
  EXPECT_TRUE(std::filesystem::exists(dir.file("report/arm_0.png")));
  const auto page = test::read_file(dir.file("report/index.html"));
  const std::string html(page.begin(), page.end());
  EXPECT_NE(html.find("Arm: commanded and measured joint motion (ARM_CMD)"), std::string::npos);
  EXPECT_NE(html.find("<h2>Arm tracking</h2>"), std::string::npos);
}

}  // namespace
}  // namespace driftlab
