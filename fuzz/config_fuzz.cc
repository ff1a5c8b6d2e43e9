// libFuzzer target: any text given to the simulator's parsers (scenario YAML, world YAML, URDF) or read as a module,
// restamp or fault config (core/config.h tables) must give a value or a one-line error naming the origin, never a
// crash, an exception or a hang.
#include <btBulletDynamicsCommon.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "controller/controller_module.h"
#include "core/config.h"
#include "estimator/estimator_module.h"
#include "faults/faults.h"
#include "replayer/replayer.h"
#include "sim/bullet_world.h"
#include "sim/robot.h"
#include "sim/scenario.h"
#include "sim/world.h"

namespace {

/// One line naming the file: the origin, or a file the text refers to (a scenario's world).
void check(const driftlab::Error& e, const std::string& origin) {
  const bool named = e.message.rfind(origin, 0) == 0 || e.message.rfind("/nonexistent/", 0) == 0;
  if (!named || e.message.find('\n') != std::string::npos) {
    std::fprintf(stderr, "error not one line naming %s: %s\n", origin.c_str(), e.message.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  // Paths into device and process trees could block or read without end; they are not configuration.
  for (const char* dir : {"/dev", "/proc", "/sys"}) {
    if (text.find(dir) != std::string::npos) return 0;
  }
  if (auto root = driftlab::config::parse_yaml(text, "m.yaml"); !root) {
    check(root.error(), "m.yaml");
  } else {
    const driftlab::config::Value v(*root, "m.yaml", "m");
    if (auto c = driftlab::estimator::estimator_config_table().parse(v); !c) check(c.error(), "m.yaml");
    if (auto c = driftlab::controller::controller_config_table().parse(v); !c) check(c.error(), "m.yaml");
    if (auto c = driftlab::replay::restamp_file_table().parse(v); !c) check(c.error(), "m.yaml");
    if (auto c = driftlab::fault_config_table().parse(v); !c) check(c.error(), "m.yaml");
  }
  if (auto w = driftlab::sim::parse_world(text, "w.yaml", "/nonexistent"); !w) check(w.error(), "w.yaml");
  if (auto s = driftlab::sim::parse_scenario(text, "s.yaml", "/nonexistent/scenarios"); !s) check(s.error(), "s.yaml");
  driftlab::sim::World empty;
  driftlab::sim::BulletWorld physics(empty);
  if (auto r = driftlab::sim::Robot::create(text, "r.urdf", physics.dynamics(), {0, 0, 0}, {}); !r) {
    check(r.error(), "r.urdf");
  } else {
    // A robot that loads must also step.
    for (int i = 0; i < 10; ++i) {
      (*r)->set_wheel_rates(1, 1, 0.001);
      physics.dynamics().stepSimulation(0.001f, 0);
      (*r)->after_step(0.001);
    }
  }
  return 0;
}
