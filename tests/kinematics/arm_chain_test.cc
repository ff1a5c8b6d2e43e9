// RobotModel (URDF tree, joint transforms, the structural errors) and ArmChain (KDL forward kinematics, Jacobian,
// inverse kinematics within the joint limits) on the shipped mobile Panda.
#include "kinematics/arm_chain.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace driftlab::kinematics {
namespace {

const std::string kUrdf = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/robots/mobile_panda.urdf";

RobotModel model() {
  auto m = RobotModel::load(kUrdf);
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  return std::move(*m);
}

TEST(RobotModel, ReadsTheTreeWithLimitsAndLines) {
  const RobotModel m = model();
  EXPECT_EQ(m.name(), "mobile_panda");
  EXPECT_EQ(m.root(), "base_link");
  const ModelJoint* j4 = m.joint("panda_joint4");
  ASSERT_NE(j4, nullptr);
  EXPECT_EQ(j4->type, JointType::kRevolute);
  EXPECT_EQ(j4->parent, "panda_link3");
  EXPECT_NEAR(j4->limits.lower, -3.0718, 1e-12);
  EXPECT_NEAR(j4->limits.upper, -0.0698, 1e-12);
  EXPECT_NEAR(j4->limits.velocity, 2.175, 1e-12);
  EXPECT_NEAR(j4->limits.effort, 87, 1e-12);
  EXPECT_GT(j4->line, 1);
  EXPECT_NE(m.where(*j4).find("mobile_panda.urdf:" + std::to_string(j4->line) + ": joint 'panda_joint4'"),
            std::string::npos);
  auto path = m.path("panda_link0", "panda_hand_tcp");
  ASSERT_TRUE(path.ok());
  EXPECT_EQ(path->size(), 10u);  // 7 revolute, link8, hand, tcp
  EXPECT_FALSE(m.path("panda_hand", "base_link").ok());
}

TEST(ArmChain, ForwardKinematicsIsThePandas) {
  const RobotModel m = model();
  auto arm = ArmChain::create(m, "panda_link0", "panda_link8", true);
  ASSERT_TRUE(arm.ok()) << arm.error().message;
  ASSERT_EQ(arm->dof(), 7);
  // At zero the flange is 88 mm forward of the base axis, 0.333 + 0.316 + 0.384 - 0.107 m up, facing down
  // (Franka's documented zero pose).
  const Eigen::Isometry3d zero = arm->fk(Eigen::VectorXd::Zero(7));
  EXPECT_TRUE(zero.translation().isApprox(Eigen::Vector3d(0.088, 0, 0.926), 1e-9)) << zero.translation().transpose();
  EXPECT_NEAR(zero.rotation().col(2).z(), -1, 1e-9);
  // The ready pose of franka_ros: flange at (0.307, 0, 0.590), to the millimetre given.
  Eigen::VectorXd ready(7);
  ready << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  EXPECT_LT((arm->fk(ready).translation() - Eigen::Vector3d(0.307, 0, 0.590)).norm(), 5e-4)
      << arm->fk(ready).translation().transpose();
  // The same pose from the URDF tree joint by joint (what the robot state publisher does).
  auto tree = m.pose_in("panda_link0", "panda_link8", [&](const std::string& name) {
    return ready[std::stoi(name.substr(std::string("panda_joint").size())) - 1];
  });
  EXPECT_TRUE(tree.isApprox(arm->fk(ready), 1e-12));
}

TEST(ArmChain, JacobianIsTheDerivativeOfForwardKinematics) {
  const RobotModel m = model();
  auto arm = ArmChain::create(m, "panda_link0", "panda_hand_tcp", true);
  ASSERT_TRUE(arm.ok());
  Eigen::VectorXd q(7);
  q << 0.3, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7;
  const Eigen::MatrixXd j = arm->jacobian(q);
  ASSERT_EQ(j.rows(), 6);
  for (int i = 0; i < 7; ++i) {
    Eigen::VectorXd dq = Eigen::VectorXd::Zero(7);
    dq[i] = 1e-7;
    const Eigen::Vector3d v = (arm->fk(q + dq).translation() - arm->fk(q - dq).translation()) / 2e-7;
    EXPECT_LT((v - j.col(i).head<3>()).norm(), 1e-6) << "joint " << i;  // the tcp is on joint 7's axis: ~0
  }
}

TEST(ArmChain, InverseKinematicsReachesPosesWithinTheLimits) {
  const RobotModel m = model();
  auto arm = ArmChain::create(m, "panda_link0", "panda_hand_tcp", true);
  ASSERT_TRUE(arm.ok());
  std::mt19937 rng(3);
  Eigen::VectorXd ready(7);
  ready << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  int converged = 0;
  for (int trial = 0; trial < 50; ++trial) {
    // A reachable target: a random configuration near ready; IK from ready must reach it.
    Eigen::VectorXd q = ready;
    for (int i = 0; i < 7; ++i) q[i] += std::uniform_real_distribution<double>(-0.4, 0.4)(rng);
    for (int i = 0; i < 7; ++i) {
      q[i] = std::clamp(q[i], arm->limits()[static_cast<size_t>(i)].lower, arm->limits()[static_cast<size_t>(i)].upper);
    }
    const IkResult r = arm->ik(arm->fk(q), ready);
    if (!r.converged) continue;
    ++converged;
    EXPECT_LT(r.position_error, 1e-5);
    EXPECT_LT(r.angle_error, 1e-5);
    for (int i = 0; i < 7; ++i) {
      EXPECT_GE(r.q[i], arm->limits()[static_cast<size_t>(i)].lower - 1e-12);
      EXPECT_LE(r.q[i], arm->limits()[static_cast<size_t>(i)].upper + 1e-12);
    }
  }
  // Damped least squares converges from a seed 0.4 rad per joint away nearly always.
  EXPECT_GE(converged, 45);
}

/// A copy of the shipped URDF with one edit.
std::string edited(const std::string& from, const std::string& to) {
  const RobotModel m = model();
  std::string xml = m.xml();
  const auto at = xml.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return xml.replace(at, from.size(), to);
}

TEST(RobotModel, BadUrdfsAreOneLineNamingTheElement) {
  // A joint whose child link is missing.
  auto missing =
      RobotModel::parse(edited("<child link=\"panda_link5\"/>", "<child link=\"panda_link9\"/>"), "arm.urdf");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("joint 'panda_joint5': its child link 'panda_link9' does not exist"),
            std::string::npos)
      << missing.error().message;
  EXPECT_EQ(missing.error().message.rfind("arm.urdf:", 0), 0u);
  // A loop: link3's joint hangs it below link5, itself below link3.
  auto loop = RobotModel::parse(edited("<parent link=\"panda_link2\"/>\n    <child link=\"panda_link3\"/>",
                                       "<parent link=\"panda_link5\"/>\n    <child link=\"panda_link3\"/>"),
                                "arm.urdf");
  ASSERT_FALSE(loop.ok());
  EXPECT_NE(loop.error().message.find("closes a loop"), std::string::npos) << loop.error().message;
  // A joint without limits where the controller needs them.
  auto free = RobotModel::parse(
      edited("<joint name=\"panda_joint6\" type=\"revolute\">", "<joint name=\"panda_joint6\" type=\"continuous\">"),
      "arm.urdf");
  ASSERT_TRUE(free.ok());
  auto chain = ArmChain::create(*free, "panda_link0", "panda_hand_tcp", true);
  ASSERT_FALSE(chain.ok());
  EXPECT_NE(chain.error().message.find("arm.urdf:"), std::string::npos);
  EXPECT_NE(chain.error().message.find("joint 'panda_joint6': is continuous"), std::string::npos)
      << chain.error().message;
  EXPECT_EQ(chain.error().message.find('\n'), std::string::npos);
  // Without the need for limits the same chain is fine (the analyzers' FK).
  EXPECT_TRUE(ArmChain::create(*free, "panda_link0", "panda_hand_tcp", false).ok());
}

}  // namespace
}  // namespace driftlab::kinematics
