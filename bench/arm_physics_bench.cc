// The peer of the manipulator's simulation benchmark (scripts/bench arm): the same robot in the same Bullet world,
// stepped at the scenario's rate with its solver iterations, each arm joint's motor driven towards a slow sinusoid
// about the scenario's home pose by a proportional loop, and nothing else: no commander (IK), no trajectory
// controller, no sensors, no TF, no log. What Bullet alone costs for this robot, so that the benchmark says what
// the rest of `driftlab sim` adds to it.
//   arm_physics_bench SCENARIO [SECONDS]   prints {"simulated_s", "wall_s", "real_time_factor"} as JSON
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>

#include <btBulletDynamicsCommon.h>

#include "core/wall_clock.h"
#include "kinematics/arm_chain.h"
#include "sim/bullet_world.h"
#include "sim/robot.h"
#include "sim/scenario.h"

namespace {

int run(int argc, char** argv) {
  using namespace driftlab;
  if (argc < 2) {
    std::fprintf(stderr, "usage: arm_physics_bench SCENARIO [SECONDS]\n");
    return 2;
  }
  auto sc = sim::load_scenario(argv[1]);
  if (!sc) return std::fprintf(stderr, "%s\n", sc.error().message.c_str()), 2;
  if (!sc->arm.enabled) return std::fprintf(stderr, "%s: no arm\n", argv[1]), 2;
  const double seconds = argc > 2 ? std::atof(argv[2]) : sc->duration;
  auto model = kinematics::RobotModel::load(sc->urdf_path);
  if (!model) return std::fprintf(stderr, "%s\n", model.error().message.c_str()), 2;
  auto chain = kinematics::ArmChain::create(*model, sc->arm.commander.base_link, sc->arm.commander.tip_link, true);
  if (!chain) return std::fprintf(stderr, "%s\n", chain.error().message.c_str()), 2;

  Stopwatch watch;  // start-up included, as `driftlab sim` reports it
  sim::BulletWorld physics(sc->world);
  physics.dynamics().getSolverInfo().m_numIterations = sc->solver_iterations;
  auto robot = sim::Robot::load(sc->urdf_path, physics.dynamics(), sc->start, sc->drive);
  if (!robot) return std::fprintf(stderr, "%s\n", robot.error().message.c_str()), 2;
  std::vector<int> index;
  std::vector<double> home;
  std::map<std::string, double> initial;
  for (size_t i = 0; i < chain->joint_names().size(); ++i) {
    index.push_back((*robot)->joint_index(chain->joint_names()[i]));
    home.push_back(i < sc->arm.commander.home.size() ? sc->arm.commander.home[i] : 0.0);
    initial[chain->joint_names()[i]] = home.back();
  }
  if (auto s = (*robot)->set_initial_positions(initial); !s)
    return std::fprintf(stderr, "%s\n", s.message().c_str()), 2;
  (*robot)->ignore_self_collisions();
  const double dt = sc->physics_step;
  const auto steps = static_cast<long>(std::llround(seconds / dt));
  for (long k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    (*robot)->set_wheel_rates(0, 0, dt);
    const std::vector<sim::JointReading> joints = (*robot)->joints();
    for (size_t i = 0; i < index.size(); ++i) {
      const double target = home[i] + 0.3 * std::sin(2 * M_PI * 0.2 * t + static_cast<double>(i));
      const double rate = 30 * (target - joints[static_cast<size_t>(index[i])].position);
      (*robot)->set_joint_rate(index[i], rate, chain->limits()[i].effort, dt);
    }
    physics.dynamics().stepSimulation(static_cast<btScalar>(dt), 0);
    (*robot)->after_step(dt);
  }
  const double wall = watch.seconds();
  std::printf("{\"simulated_s\": %.3f, \"wall_s\": %.6f, \"real_time_factor\": %.3f}\n", seconds, wall, seconds / wall);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "arm_physics_bench: %s\n", e.what());
    return 1;
  }
}
