// read_multirotor / load_multirotor: the shipped quadrotor URDF against the flight stack's vehicle model, and the
// one-line errors for drone URDFs the simulator cannot fly.
#include <gtest/gtest.h>

#include <regex>

#include "flight/vehicle.h"
#include "sim/robot.h"

namespace driftlab::sim {
namespace {

const std::string kQuadrotor = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/robots/quadrotor.urdf";

// The flight stack flies the shipped quadrotor with VehicleModel's defaults: the URDF must say the same mass,
// inertia and rotor layout, or the simulated vehicle and the one the controllers assume would differ.
TEST(Multirotor, TheShippedQuadrotorIsTheFlightStacksVehicle) {
  auto spec = load_multirotor(kQuadrotor);
  ASSERT_TRUE(spec.ok()) << spec.error().message;
  const flight::VehicleModel model;
  EXPECT_EQ(spec->name, "quadrotor");
  EXPECT_EQ(spec->base_link, "base_link");
  EXPECT_NEAR(spec->mass, model.mass, 1e-9);
  // Principal moments within 1% (the URDF's figures are rounded to 1e-6 kg*m^2), and no products of inertia.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(spec->inertia(i, i), model.inertia(i), 0.01 * model.inertia(i)) << i;
  EXPECT_NEAR(spec->inertia(0, 1), 0, 1e-9);
  EXPECT_NEAR(spec->inertia(0, 2), 0, 1e-9);
  EXPECT_NEAR(spec->inertia(1, 2), 0, 1e-9);
  ASSERT_EQ(spec->rotors.size(), model.rotors.size());
  for (const RotorSpec& r : spec->rotors) {
    // rotor_i_joint is VehicleModel's rotor i: same place (0.25 m arms, X layout) and the same spin.
    std::smatch m;
    ASSERT_TRUE(std::regex_match(r.joint, m, std::regex("rotor_([0-3])_joint"))) << r.joint;
    const flight::Rotor& expected = model.rotors[static_cast<std::size_t>(std::stoi(m[1]))];
    EXPECT_NEAR(r.position.x(), expected.x, 1e-4) << r.joint;
    EXPECT_NEAR(r.position.y(), expected.y, 1e-4) << r.joint;
    EXPECT_NEAR(r.position.head<2>().norm(), 0.25, 1e-3) << r.joint;
    EXPECT_EQ(r.direction, expected.direction) << r.joint;
  }
}

std::string body(const std::string& mass = "1.0") {
  return "  <link name=\"base_link\">\n    <inertial><mass value=\"" + mass +
         "\"/><inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.02\"/></inertial>\n  </link>\n";
}
std::string rotor(const std::string& axis, const std::string& mass = "0.05") {
  return "  <link name=\"rotor_0\">\n    <inertial><mass value=\"" + mass +
         "\"/><inertia ixx=\"1e-5\" ixy=\"0\" ixz=\"0\" iyy=\"1e-5\" iyz=\"0\" izz=\"2e-5\"/></inertial>\n  </link>\n"
         "  <joint name=\"rotor_0_joint\" type=\"continuous\">\n    <parent link=\"base_link\"/><child "
         "link=\"rotor_0\"/>\n"
         "    <origin xyz=\"0.18 0.18 0.04\"/>\n" +
         axis + "  </joint>\n";
}
std::string robot(const std::string& inner) { return "<robot name=\"bad\">\n" + inner + "</robot>\n"; }

TEST(Multirotor, BadDroneFilesGetOneLineNamingFileAndElement) {
  struct Case {
    std::string xml, message;
  };
  const std::vector<Case> cases = {
      {robot(body()), "bad.urdf:2: link 'base_link': no rotor joints (continuous joints on the base link)"},
      {robot(body("0") + rotor("    <axis xyz=\"0 0 1\"/>\n")),
       "bad.urdf:2: link 'base_link': mass must be positive (a rotor or body without mass cannot fly)"},
      {robot(body() + rotor("    <axis xyz=\"0 0 1\"/>\n", "0")),
       "bad.urdf:5: link 'rotor_0': mass must be positive (a rotor or body without mass cannot fly)"},
      {robot(body() + rotor("")),
       "bad.urdf:8: joint 'rotor_0_joint': a rotor joint needs an <axis> (its spin axis, 0 0 1 or 0 0 -1)"},
      {robot(body() + rotor("    <axis xyz=\"1 0 0\"/>\n")),
       "bad.urdf:8: joint 'rotor_0_joint': a rotor's axis must be along the body's z (0 0 1 or 0 0 -1)"},
      {"<robot name=\"bad\">\n  <link name=\"base_link\">\n", "bad.urdf:"},
  };
  for (const Case& c : cases) {
    auto spec = read_multirotor(c.xml, "bad.urdf");
    ASSERT_FALSE(spec.ok()) << c.xml;
    EXPECT_EQ(spec.error().message.rfind(c.message, 0), 0u) << spec.error().message;
    EXPECT_EQ(spec.error().message.find('\n'), std::string::npos) << spec.error().message;
  }
  // A good one of the same shape reads.
  auto good = read_multirotor(robot(body() + rotor("    <axis xyz=\"0 0 -1\"/>\n")), "good.urdf");
  ASSERT_TRUE(good.ok()) << good.error().message;
  ASSERT_EQ(good->rotors.size(), 1u);
  EXPECT_EQ(good->rotors[0].direction, -1);
  EXPECT_NEAR(good->mass, 1.05, 1e-12);
  auto missing = load_multirotor("/nonexistent/drone.urdf");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().message, "/nonexistent/drone.urdf: cannot open the URDF file: No such file or directory");
}

}  // namespace
}  // namespace driftlab::sim
