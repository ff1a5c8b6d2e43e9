// The mobile manipulator scenario (sim/scenarios/manipulator.yaml) end to end: one pick-and-place cycle simulated,
// its log read back. The end effector's ground truth against the kinematics' FK of the measured joints (the
// simulator, controller and analyzers share one FK) and of the controller's desired joints (the issue's "tracked
// within 1 cm and 1 degree"), the joint limits, every command taken, the TF the robot state publisher wrote; the
// latency scenario (every command 120 ms late, the arm lags) and the drifting commander clock (stale commands).
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "analyzers/timing.h"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_result_t.hpp"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/robot_description_t.hpp"
#include "driftlab/tf_t.hpp"
#include "kinematics/arm_chain.h"
#include "sim/simulator.h"
#include "tests/doc_figures.h"
#include "tests/test_util.h"

namespace driftlab::sim {
namespace {

using test::decode;

const std::string kScenarios = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/";
constexpr double kPi = 3.14159265358979323846;

/// Simulates `seconds` of a shipped scenario into `out` and reads the log back.
std::vector<test::OwnedEvent> simulate(const std::string& scenario, double seconds, const std::string& out) {
  auto sc = load_scenario(kScenarios + scenario);
  EXPECT_TRUE(sc.ok()) << sc.error().message;
  if (!sc.ok()) return {};
  sc->duration = seconds;
  auto sim = Simulation::create(*sc);
  EXPECT_TRUE(sim.ok()) << sim.error().message;
  if (!sim.ok()) return {};
  SimOptions o;
  o.out = out;
  auto r = (*sim)->run(o);
  EXPECT_TRUE(r.ok()) << r.error().message;
  return test::read_all(out);
}

std::vector<const test::OwnedEvent*> on(const std::vector<test::OwnedEvent>& events, const std::string& channel) {
  std::vector<const test::OwnedEvent*> out;
  for (const auto& e : events) {
    if (e.channel == channel) out.push_back(&e);
  }
  return out;
}

Eigen::Isometry3d pose(const driftlab::pose_t& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  t.linear() = Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
                   .normalized()
                   .toRotationMatrix();
  return t;
}

class Manipulator : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    // One cycle of the plan: 13.8 s.
    events_ = new std::vector<test::OwnedEvent>(simulate("manipulator.yaml", kCycle, dir_->file("arm.lcm")));
  }
  static void TearDownTestSuite() {
    delete events_;
    delete dir_;
  }
  static constexpr double kCycle = 14;  // [s]
  static std::vector<const test::OwnedEvent*> on(const std::string& channel) { return sim::on(*events_, channel); }
  static kinematics::ArmChain chain() {
    auto d = on("ROBOT_DESCRIPTION");
    EXPECT_EQ(d.size(), 1u);
    auto model = kinematics::RobotModel::parse(decode<driftlab::robot_description_t>(*d.at(0)).urdf, "log");
    EXPECT_TRUE(model.ok());
    auto c = kinematics::ArmChain::create(*model, "base_link", "panda_hand_tcp", true);
    EXPECT_TRUE(c.ok());
    return std::move(*c);
  }
  /// Poses of a ground-truth channel by their stamp [us].
  static std::map<int64_t, Eigen::Isometry3d> truth(const std::string& channel,
                                                    const std::vector<test::OwnedEvent>* events = nullptr) {
    std::map<int64_t, Eigen::Isometry3d> out;
    for (const auto* e : sim::on(events != nullptr ? *events : *events_, channel)) {
      const auto p = decode<driftlab::pose_t>(*e);
      out[p.header.utime] = pose(p);
    }
    return out;
  }
  static inline test::TempDir* dir_ = nullptr;
  static inline std::vector<test::OwnedEvent>* events_ = nullptr;
};

TEST_F(Manipulator, EndEffectorTracksThePlanWithin1cmAnd1Degree) {
  const kinematics::ArmChain arm = chain();
  const auto base = truth("GROUND_TRUTH"), ee = truth("EE_TRUTH");
  double worst_fk_m = 0, worst_fk_rad = 0, worst_m = 0, worst_rad = 0, travel = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  int compared = 0;
  for (const auto* e : on("ARM_STATE")) {
    const auto s = decode<driftlab::joint_trajectory_state_t>(*e);
    const auto b = base.find(s.header.utime), t = ee.find(s.header.utime);
    if (b == base.end() || t == ee.end()) continue;
    ++compared;
    const Eigen::Isometry3d measured = b->second.inverse() * t->second;  // the hand in base_link, from the physics
    const Eigen::Isometry3d fk = arm.fk(Eigen::Map<const Eigen::VectorXd>(s.actual_positions.data(), 7));
    const Eigen::Isometry3d want = arm.fk(Eigen::Map<const Eigen::VectorXd>(s.desired_positions.data(), 7));
    worst_fk_m = std::max(worst_fk_m, kinematics::position_distance(measured, fk));
    worst_fk_rad = std::max(worst_fk_rad, kinematics::angle_distance(measured, fk));
    worst_m = std::max(worst_m, kinematics::position_distance(measured, want));
    worst_rad = std::max(worst_rad, kinematics::angle_distance(measured, want));
    if (compared == 1) first = t->second.translation();
    travel = std::max(travel, (measured.translation() - (b->second.inverse() * first)).norm());
  }
  EXPECT_GT(compared, 1300);  // ARM_STATE and the truths at 100 Hz on the same steps
  // The physics' links are where the URDF's FK puts them for the measured joints, but for the slack of Bullet's
  // hinge constraints under the links' weight at 12 solver iterations (1.4 mm and 2.6 mrad at most in this run):
  // a wrong frame, axis or sign would be centimetres off.
  EXPECT_LT(worst_fk_m, 3e-3);
  EXPECT_LT(worst_fk_rad, 5e-3);
  // The bar: 1 cm and 1 degree from what the controller wants, over the whole run.
  EXPECT_LT(worst_m, 0.01);
  EXPECT_LT(worst_rad, kPi / 180);
  EXPECT_GT(travel, 0.3);  // it did move: the pick and place are 0.55 m apart
  std::printf("EE vs desired: max %.4f m, %.4f deg; FK vs physics %.5f m\n", worst_m, worst_rad * 180 / kPi,
              worst_fk_m);
  test::expect_doc_text_figures("docs/simulator.md", "The clean scenario tracks the plan within ",
                                " degree at the end effector", {worst_m * 1e3, worst_rad * 180 / kPi});
  test::expect_doc_text_figures("docs/simulator.md", "and the links sit within ", " mrad of the URDF's FK",
                                {worst_fk_m * 1e3, worst_fk_rad * 1e3});
}

TEST_F(Manipulator, JointsStayWithinTheirLimitsAndEveryCommandIsTaken) {
  const kinematics::ArmChain arm = chain();
  const auto states = on("JOINT_STATES");
  ASSERT_GT(states.size(), 1300u);
  for (const auto* e : states) {
    const auto s = decode<driftlab::joint_state_t>(*e);
    for (size_t i = 0; i < s.name.size(); ++i) {
      for (int j = 0; j < arm.dof(); ++j) {
        const kinematics::JointLimits& l = arm.limits()[static_cast<size_t>(j)];
        if (s.name[i] != arm.joint_names()[static_cast<size_t>(j)]) continue;
        EXPECT_GE(s.position[i], l.lower - 1e-3) << s.name[i];
        EXPECT_LE(s.position[i], l.upper + 1e-3) << s.name[i];
        EXPECT_LE(std::abs(s.velocity[i]), l.velocity * 1.05) << s.name[i];
      }
    }
  }
  // A command every 50 ms, each replacing the one before: none rejected, none aborted.
  EXPECT_EQ(on("ARM_CMD").size(), 281u);
  for (const auto* e : on("ARM_RESULT")) {
    const auto r = decode<driftlab::joint_trajectory_result_t>(*e);
    ADD_FAILURE() << r.status << ": " << r.message;
  }
}

TEST_F(Manipulator, RobotStatePublisherPutsEveryJointOnTf) {
  const auto tfs = on("TF_JOINTS");
  ASSERT_GT(tfs.size(), 600u);  // 50 Hz
  const auto tf = decode<driftlab::tf_t>(*tfs.back());
  std::map<std::string, std::string> parent;
  for (const auto& t : tf.transforms) parent[t.child_frame_id] = t.header.frame_id;
  for (const auto& t : decode<driftlab::tf_t>(*on("TF_STATIC").back()).transforms) {
    parent[t.child_frame_id] = t.header.frame_id;
  }
  for (const auto& t : decode<driftlab::tf_t>(*on("TF_MAP").back()).transforms)
    parent[t.child_frame_id] = t.header.frame_id;
  for (const auto& t : decode<driftlab::tf_t>(*on("TF").back()).transforms)
    parent[t.child_frame_id] = t.header.frame_id;
  // The hand reaches map through the arm, base_link and odom.
  std::vector<std::string> path{"panda_hand_tcp"};
  while (parent.count(path.back()) != 0 && path.size() < 30) path.push_back(parent[path.back()]);
  ASSERT_GE(path.size(), 4u);
  EXPECT_EQ(path.back(), "map");
  EXPECT_EQ(path[path.size() - 2], "odom");
  EXPECT_EQ(path[path.size() - 3], "base_link");
}

/// The end effector in the base's frame by stamp [us], from the ground truths.
std::map<int64_t, Eigen::Vector3d> hand_in_base(const std::map<int64_t, Eigen::Isometry3d>& base,
                                                const std::map<int64_t, Eigen::Isometry3d>& ee) {
  std::map<int64_t, Eigen::Vector3d> out;
  for (const auto& [t, pose] : ee) {
    if (auto b = base.find(t); b != base.end()) out[t] = (b->second.inverse() * pose).translation();
  }
  return out;
}

/// RMS distance between a(t) and b(t - shift) [m].
double rms_shifted(const std::map<int64_t, Eigen::Vector3d>& a, const std::map<int64_t, Eigen::Vector3d>& b,
                   int64_t shift_us) {
  double sum = 0;
  int n = 0;
  for (const auto& [t, p] : a) {
    if (auto q = b.find(t - shift_us); q != b.end()) {
      sum += (p - q->second).squaredNorm();
      ++n;
    }
  }
  return n > 0 ? std::sqrt(sum / n) : 1e9;
}

TEST_F(Manipulator, LatencyScenarioDelaysEveryCommandAndTheArmLags) {
  const auto late = simulate("manipulator_latency.yaml", kCycle, dir_->file("latency.lcm"));
  // Every command arrives 120 ms after its (honest) stamp.
  const auto cmds = sim::on(late, "ARM_CMD");
  ASSERT_EQ(cmds.size(), 281u);
  for (const auto* e : cmds) {
    EXPECT_EQ(e->utime - decode<driftlab::joint_trajectory_t>(*e).header.utime, 120'000);
  }
  // The hand follows the clean run's motion late: compared at the same time it is centimetres off (14 mm RMS in
  // this run), shifted by the lag it is within a third of that. The lag is less than the 120 ms of transport: the
  // commander's correction, from joint states it sees now, pulls part of it back.
  const auto clean = hand_in_base(truth("GROUND_TRUTH"), truth("EE_TRUTH"));
  const auto lagged = hand_in_base(truth("GROUND_TRUTH", &late), truth("EE_TRUTH", &late));
  const double same_time = rms_shifted(lagged, clean, 0);
  double best = same_time;
  int64_t best_shift = 0;
  for (int64_t shift = 10'000; shift <= 200'000; shift += 10'000) {
    if (const double e = rms_shifted(lagged, clean, shift); e < best) {
      best = e;
      best_shift = shift;
    }
  }
  EXPECT_GT(same_time, 0.01);
  EXPECT_LT(best, same_time / 3);
  EXPECT_GE(best_shift, 50'000);
  EXPECT_LE(best_shift, 120'000);
  // driftlab diagnose measures the loop's delay from the motion: the joints repeat the commanded positions 120 ms
  // after the commands' stamps (the issue asks for 5 ms), where the clean run's repeat them at once (the
  // controller tracks its plan within a physics step or two).
  for (const auto& [log, delay] : {std::pair{dir_->file("latency.lcm"), 0.120}, {dir_->file("arm.lcm"), 0.0}}) {
    const auto d = analyzers::diagnose(log);
    ASSERT_TRUE(d.ok()) << d.error().message;
    ASSERT_EQ(d->command_loops.size(), 1u);
    const analyzers::CommandLoop& loop = d->command_loops[0];
    EXPECT_EQ(loop.command_channel, "ARM_CMD");
    EXPECT_EQ(loop.state_channel, "JOINT_STATES");
    EXPECT_NEAR(loop.command_period_s, 0.05, 1e-6);
    ASSERT_TRUE(loop.delay_valid) << log << ": confidence " << loop.confidence;
    EXPECT_NEAR(loop.delay_s, delay, 0.005) << log;
    EXPECT_GT(loop.confidence, 0.9) << log;
    EXPECT_EQ(loop.stale, 0) << log;
  }
  std::printf("latency: hand %.4f m RMS from the clean run, %.4f m at its best shift of %lld ms\n", same_time, best,
              static_cast<long long>(best_shift / 1000));
  test::expect_doc_text_figures("docs/simulator.md",
                                "follows the clean run's motion late: ", " ms (the commander's correction",
                                {same_time * 1e3, best * 1e3, static_cast<double>(best_shift) / 1e3});
}

TEST(ManipulatorClock, CommandsStampedInThePastAreRejectedAsStale) {
  test::TempDir dir;
  const auto events = simulate("manipulator_clock.yaml", 30, dir.file("clock.lcm"));
  // The commander's clock loses 2%: at t s into the run its stamps are 0.02 t s behind, and a trajectory whose
  // 0.5 s horizon ends before it arrives (0.02 t > 0.5: after 25 s, the command at 25.00 s ends as it arrives) is
  // stale.
  int stale = 0, commands_after = 0;
  // Commands up to 29.9 s, and their results, which the controller gives one physics step (1 ms) after their
  // arrival (it takes what the output wrote before that step); the run's last step's are not written.
  auto window = [&](int64_t utime, int64_t from, int64_t to) {
    return utime - events.front().utime > from && utime - events.front().utime <= to;
  };
  for (const auto* e : sim::on(events, "ARM_CMD")) commands_after += window(e->utime, 25'000'000, 29'900'000);
  for (const auto* e : sim::on(events, "ARM_RESULT")) {
    const auto r = decode<driftlab::joint_trajectory_result_t>(*e);
    const double t = static_cast<double>(r.header.utime - events.front().utime) * 1e-6;
    if (r.status != "stale" || !window(r.header.utime, 0, 29'901'000)) continue;
    ++stale;
    EXPECT_GT(t, 25.0);
    EXPECT_NEAR(r.error, 0.02 * t - 0.5, 1e-3) << "how late, at " << t << " s";
    EXPECT_NE(r.message.find("before it arrived"), std::string::npos);
  }
  EXPECT_EQ(stale, commands_after);  // every command after 25 s, and only those
  EXPECT_GT(stale, 90);
  // driftlab diagnose names them from the commands alone (stamp, plan, arrival): the same commands, the first
  // after 25 s; the delay is not measured (it grows with the clock's drift, and the arm stops following).
  const auto d = analyzers::diagnose(dir.file("clock.lcm"));
  ASSERT_TRUE(d.ok()) << d.error().message;
  ASSERT_EQ(d->command_loops.size(), 1u);
  const analyzers::CommandLoop& loop = d->command_loops[0];
  int64_t all_after = 0;  // to the end of the log (the results stop a step before it)
  for (const auto* e : sim::on(events, "ARM_CMD")) all_after += e->utime - events.front().utime > 25'000'000;
  EXPECT_EQ(loop.stale, all_after);
  EXPECT_GE(loop.stale, stale);
  EXPECT_NEAR(loop.first_stale_s, 25.0, 0.06);
  EXPECT_NEAR(loop.stale_max_s, 0.02 * 30 - 0.5, 0.002);
  EXPECT_FALSE(loop.delay_valid);
}

}  // namespace
}  // namespace driftlab::sim
