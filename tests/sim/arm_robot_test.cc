// The mobile Panda in Bullet (sim/robots/mobile_panda.urdf through Robot): initial positions, joint motors as a
// velocity command interface, the hinge limits, and the physics' link poses against the kinematics' FK.
#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "kinematics/arm_chain.h"
#include "sim/bullet_world.h"
#include "sim/robot.h"

namespace driftlab::sim {
namespace {

const std::string kUrdf = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/robots/mobile_panda.urdf";
constexpr double kDt = 0.001;
const double kReady[7] = {0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4};

struct ArmRig {
  World world;
  BulletWorld physics{world};
  std::unique_ptr<Robot> robot;
  std::vector<int> index;
  ArmRig() {
    physics.dynamics().getSolverInfo().m_numIterations = 20;
    auto r = Robot::load(kUrdf, physics.dynamics(), {0, 0, 0}, {});
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    robot = std::move(*r);
    robot->ignore_self_collisions();
    std::map<std::string, double> q;
    for (int i = 0; i < 7; ++i) q["panda_joint" + std::to_string(i + 1)] = kReady[i];
    EXPECT_TRUE(robot->set_initial_positions(q).ok());
    for (int i = 0; i < 7; ++i) index.push_back(robot->joint_index("panda_joint" + std::to_string(i + 1)));
  }
  void step(const std::vector<double>& rates) {
    robot->set_wheel_rates(0, 0, kDt);
    for (int i = 0; i < 7; ++i)
      robot->set_joint_rate(index[static_cast<size_t>(i)], rates[static_cast<size_t>(i)], 87, kDt);
    physics.dynamics().stepSimulation(static_cast<btScalar>(kDt), 0);
    robot->after_step(kDt);
  }
  void run(const std::vector<double>& rates, double seconds) {
    for (int s = 0; s < static_cast<int>(std::lround(seconds / kDt)); ++s) step(rates);
  }
  /// Drives every joint to `target` [rad] with a PI position loop through the velocity interface (the joint
  /// trajectory controller's inner loop and gains, without its feed-forward).
  void servo(const Eigen::VectorXd& target, double seconds) {
    Eigen::VectorXd integral = Eigen::VectorXd::Zero(7);
    for (int s = 0; s < static_cast<int>(std::lround(seconds / kDt)); ++s) {
      const Eigen::VectorXd e = target - q();
      integral += e * kDt;
      std::vector<double> rates(7);
      for (int i = 0; i < 7; ++i)
        rates[static_cast<size_t>(i)] = std::clamp(30.0 * e[i] + 300.0 * integral[i], -2.0, 2.0);
      step(rates);
    }
  }
  Eigen::VectorXd q() const {
    Eigen::VectorXd out(7);
    const auto joints = robot->joints();
    for (int i = 0; i < 7; ++i) out[i] = joints[static_cast<size_t>(index[static_cast<size_t>(i)])].position;
    return out;
  }
};

TEST(ArmRobot, HoldsItsInitialPoseAndMovesAlongItsAxes) {
  ArmRig rig;
  // Placed at the ready pose, the links start there.
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(rig.q()[i], kReady[i], 1e-9) << "joint " << i + 1;
  // Bullet's iterative solver lets a motor fall short of its rate under gravity (the links hang from a 60 kg base
  // through 20 solver iterations): joint 4 sags about 0.1 rad/s with its motor at zero rate. The sense of each
  // axis and the motor's sign are checked on joints that carry little load, with a margin for that sag.
  std::vector<double> rates(7, 0.0);
  rates[0] = -0.3;  // joint 1's axis is vertical: no gravity load
  rates[6] = 0.5;   // joint 7: the hand, about its own axis
  const Eigen::VectorXd before = rig.q();
  rig.run(rates, 1.0);
  EXPECT_NEAR(rig.q()[0] - before[0], -0.3, 0.03);
  EXPECT_NEAR(rig.q()[6] - before[6], 0.5, 0.05);
  // Closed in a PI position loop, as the controller drives them, every joint reaches its target and holds it to
  // 1 mrad: the integral takes up the sag (a P loop alone would stay 0.1 rad/s / 30/s = 4 mrad short).
  Eigen::Map<const Eigen::VectorXd> ready(kReady, 7);
  Eigen::VectorXd target = ready;
  target[3] += 0.5;
  target[1] += 0.3;
  target[5] -= 0.4;
  rig.servo(target, 2.0);
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(rig.q()[i], target[i], 1e-3) << "joint " << i + 1;
  // The physics' hand where the URDF's kinematics put it for the measured joints.
  auto model = kinematics::RobotModel::load(kUrdf);
  ASSERT_TRUE(model.ok());
  auto chain = kinematics::ArmChain::create(*model, "base_link", "panda_hand_tcp", true);
  ASSERT_TRUE(chain.ok());
  const Eigen::Isometry3d truth = rig.robot->link_pose("base_link").inverse() * rig.robot->link_pose("panda_hand_tcp");
  const Eigen::Isometry3d fk = chain->fk(rig.q());
  EXPECT_LT(kinematics::position_distance(truth, fk), 1e-3)
      << truth.translation().transpose() << " vs " << fk.translation().transpose();
  EXPECT_LT(kinematics::angle_distance(truth, fk), 2e-3);
}

TEST(ArmRobot, HingeLimitsHoldTheUrdfRange) {
  ArmRig rig;
  // Joint 4 driven up past its upper limit (-0.0698 rad) stops there.
  std::vector<double> rates(7, 0.0);
  rates[3] = 2.0;
  rig.run(rates, 2.0);
  EXPECT_NEAR(rig.q()[3], -0.0698, 0.02);
}

}  // namespace
}  // namespace driftlab::sim
