// The mixer: demands it can meet come out exactly (thrust and torques from the motor commands); when a motor
// saturates, roll and pitch keep priority over yaw and the rate controller is told which axes were cut. The vehicle
// model's keys: a rotor layout that cannot make roll or pitch torques is refused, naming the key.
#include "flight/vehicle.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "core/config.h"

namespace driftlab::flight {
namespace {

TEST(Mixer, MeetsFeasibleDemandsExactly) {
  const VehicleModel model;
  const Mixer mixer(model);
  const double hover = model.mass * 9.81;
  for (const Eigen::Vector3d& torque :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.3, -0.2, 0.05), Eigen::Vector3d(-0.5, 0.4, -0.1)}) {
    const Mix m = mixer.mix(hover, torque);
    const Eigen::Vector4d e = mixer.effect(m.control);
    EXPECT_NEAR(e(0), hover, 1e-9);
    EXPECT_LT((e.tail<3>() - torque).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_EQ(m.saturated[0] | m.saturated[1] | m.saturated[2], 0);
    EXPECT_FALSE(m.thrust_limited);
  }
  // Hover: every motor at the same command, a quarter of the weight each.
  for (double u : mixer.mix(hover, Eigen::Vector3d::Zero()).control)
    EXPECT_NEAR(u * model.max_rotor_thrust, hover / 4, 1e-9);
}

TEST(Mixer, KeepsRollAndPitchWhenYawSaturates) {
  const VehicleModel model;
  const Mixer mixer(model);
  const double hover = model.mass * 9.81;
  const Eigen::Vector3d torque(0.4, 0, 2.0);  // far more yaw than the rotors' drag can make
  const Mix m = mixer.mix(hover, torque);
  const Eigen::Vector4d e = mixer.effect(m.control);
  EXPECT_NEAR(e(1), 0.4, 1e-9);
  EXPECT_NEAR(e(2), 0, 1e-9);
  EXPECT_GT(e(3), 0);
  EXPECT_LT(e(3), 2.0);
  EXPECT_EQ(m.saturated[2], 1);
  EXPECT_EQ(m.saturated[0], 0);
  for (double u : m.control) {
    EXPECT_GE(u, 0);
    EXPECT_LE(u, 1);
  }
}

TEST(Mixer, ScalesRollAndPitchThatDoNotFitAndSaysSo) {
  const VehicleModel model;
  const Mixer mixer(model);
  const Mix m = mixer.mix(model.mass * 9.81, Eigen::Vector3d(-5, 3, 0));
  EXPECT_EQ(m.saturated[0], -1);
  EXPECT_EQ(m.saturated[1], 1);
  const Eigen::Vector4d e = mixer.effect(m.control);
  EXPECT_NEAR(e(1) / e(2), -5.0 / 3.0, 1e-6);  // the direction of the demand is kept
  for (double u : m.control) {
    EXPECT_GE(u, 0);
    EXPECT_LE(u, 1);
  }
}

TEST(VehicleModel, RotorsInALineAreRefusedNamingTheKey) {
  const YAML::Node n = YAML::Load("rotors: [[0.2, 0, 1], [0.1, 0, -1], [-0.1, 0, 1], [-0.2, 0, -1]]\n");
  auto r = vehicle_model_table().parse(config::Value(n, "drone.yaml", "vehicle"));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("drone.yaml"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("vehicle.rotors"), std::string::npos) << r.error().message;
  const YAML::Node bad = YAML::Load("rotors: [[0.2, 0.2, 2], [0.1, 0, -1], [-0.1, 0, 1], [-0.2, 0, -1]]\n");
  EXPECT_FALSE(vehicle_model_table().parse(config::Value(bad, "drone.yaml", "vehicle")));
  EXPECT_TRUE(vehicle_model_table().parse(config::Value(YAML::Load("mass: 1.5\n"), "drone.yaml", "vehicle")));
}

}  // namespace
}  // namespace driftlab::flight
