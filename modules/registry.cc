#include "modules/registry.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>

#include "controller/controller_module.h"
#include "estimator/drone_estimator_module.h"
#include "estimator/estimator_module.h"
#include "flight/flight_module.h"
#include "flight/offboard_module.h"
#include "modules/settings.h"
#include "sim/scenario.h"
#include "slam/slam_module.h"

namespace driftlab::modules {
namespace {

/// The controller's defaults from a simulator scenario: its route, start pose and follower settings.
Result<controller::ControllerConfig> controller_base(const std::string& scenario_path) {
  auto sc = sim::load_scenario(scenario_path);
  if (!sc) return sc.error();
  controller::ControllerConfig c;
  c.route = sc->route;
  c.start = {sc->start.x(), sc->start.y(), sc->start.z()};
  c.pursuit = sc->controller.pursuit;
  c.rate = sc->controller.rate;
  c.footprint_radius = sc->controller.footprint_radius;
  c.logged_channel = sc->controller.channel;
  return c;
}

/// What a module is made from: its settings (a YAML node; the config they came from, for messages and relative
/// paths), the channels the run delivers, and the notes for the user.
struct Making {
  const YAML::Node& config;
  const ModuleSettings& settings;
  const InputChannels& inputs;
  std::vector<std::string>& notes;
};

Result<std::unique_ptr<Module>> make_controller(const Making& m) {
  auto scenario = controller_scenario(m.config, m.settings);
  if (!scenario) return scenario.error();
  controller::ControllerConfig base;
  if (scenario->from_scenario) {
    std::string path = scenario->path;
    if (path.empty()) {
      path = sim::default_scenario_path();
      m.notes.push_back("controller: route, start and settings from the default scenario " + path);
    }
    auto b = controller_base(path);
    if (!b) return b.error();
    base = std::move(*b);
  }
  return controller::make_controller(m.config, m.settings.origin, std::move(base));
}

/// A row of modules/module_table.h made real: its factory (its settings' check and reference are
/// modules/settings.cc's).
struct ModuleRow {
  std::string_view name;
  Result<std::unique_ptr<Module>> (*make)(const Making& m);
};

constexpr std::array<ModuleRow, kModuleKinds.size()> kRows{{
    {"slam", [](const Making& m) { return slam::make_slam(m.config, m.settings.origin, m.inputs, &m.notes); }},
    {"estimator", [](const Making& m) { return estimator::make_estimator(m.config, m.settings.origin); }},
    {"controller", make_controller},
    {"drone_estimator", [](const Making& m) { return estimator::make_drone_estimator(m.config, m.settings.origin); }},
    {"flight", [](const Making& m) { return flight::make_flight(m.config, m.settings.origin); }},
    {"offboard", [](const Making& m) { return flight::make_offboard(m.config, m.settings.origin); }},
}};

/// The rows are the table's, in its order: a module named in one and not the other fails the build.
constexpr bool rows_follow_the_table() {
  for (size_t i = 0; i < kRows.size(); ++i) {
    if (kRows[i].name != kModuleKinds[i].name) return false;
  }
  return true;
}
static_assert(rows_follow_the_table(), "modules/registry.cc: kRows must list modules/module_table.h's modules");

}  // namespace

Result<std::vector<std::unique_ptr<Module>>> load_modules(const std::string& list, const std::string& config_path,
                                                          const InputChannels& inputs,
                                                          std::vector<std::string>& notes) {
  auto settings = read_module_settings(config_path);
  if (!settings) return settings.error();
  std::vector<std::unique_ptr<Module>> modules;
  const Status made = for_each_module(*settings, list, [&](const std::string& name, const YAML::Node& config) {
    // Every module has its row (rows_follow_the_table).
    const auto row = std::find_if(kRows.begin(), kRows.end(), [&](const ModuleRow& r) { return r.name == name; });
    auto m = row->make(Making{config, *settings, inputs, notes});
    if (!m) return Status{m.error()};
    modules.push_back(std::move(*m));
    return Status{};
  });
  if (!made) return made.error();
  return modules;
}

}  // namespace driftlab::modules
