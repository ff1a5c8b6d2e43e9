#include "modules/registry.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <sstream>

#include "controller/controller_module.h"
#include "core/config.h"
#include "estimator/drone_estimator_module.h"
#include "estimator/estimator_module.h"
#include "flight/flight_module.h"
#include "flight/offboard_module.h"
#include "sim/scenario.h"
#include "slam/slam_module.h"

namespace driftlab::modules {
namespace {

std::string line_of(const std::string& file, const YAML::Mark& mark) {
  return file + ":" + std::to_string(mark.line + 1);
}

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

Result<std::unique_ptr<Module>> make_controller(const YAML::Node& config, const std::string& origin,
                                                const std::string& config_dir, std::vector<std::string>& notes) {
  std::string scenario;
  if (config.IsMap() && config["scenario"].IsDefined()) {
    const YAML::Node node = config["scenario"];
    if (!node.IsScalar()) return Error{line_of(origin, node.Mark()) + ": controller.scenario: expected a file name"};
    scenario = node.Scalar();
    if (!scenario.empty() && scenario[0] != '/') scenario = (std::filesystem::path(config_dir) / scenario).string();
  } else if (!(config.IsMap() && config["route"].IsDefined())) {
    scenario = sim::default_scenario_path();
    notes.push_back("controller: route, start and settings from the default scenario " + scenario);
  }
  controller::ControllerConfig base;
  if (!scenario.empty()) {
    auto b = controller_base(scenario);
    if (!b) return b.error();
    base = std::move(*b);
  }
  return controller::make_controller(config, origin, std::move(base));
}

/// What a module is made from: its settings (a YAML node, the file it came from for messages, that file's folder
/// for relative paths), the channels the run delivers, and the notes for the user.
struct Making {
  const YAML::Node& config;
  const std::string& origin;
  const std::string& config_dir;
  const InputChannels& inputs;
  std::vector<std::string>& notes;
};

/// A row of modules/module_table.h made real: its settings' reference (the keys with the module's name in front)
/// and its factory.
struct ModuleRow {
  std::string_view name;
  std::string (*reference)(const std::string& prefix);
  Result<std::unique_ptr<Module>> (*make)(const Making& m);
};

constexpr std::array<ModuleRow, kModuleKinds.size()> kRows{{
    {"slam", [](const std::string& p) { return slam::slam_config_table().reference(p); },
     [](const Making& m) { return slam::make_slam(m.config, m.origin, m.inputs, &m.notes); }},
    {"estimator", [](const std::string& p) { return estimator::estimator_config_table().reference(p); },
     [](const Making& m) { return estimator::make_estimator(m.config, m.origin); }},
    {"controller", [](const std::string& p) { return controller::controller_config_table().reference(p); },
     [](const Making& m) { return make_controller(m.config, m.origin, m.config_dir, m.notes); }},
    {"drone_estimator", [](const std::string& p) { return estimator::drone_estimator_config_table().reference(p); },
     [](const Making& m) { return estimator::make_drone_estimator(m.config, m.origin); }},
    {"flight", [](const std::string& p) { return flight::flight_config_table().reference(p); },
     [](const Making& m) { return flight::make_flight(m.config, m.origin); }},
    {"offboard", [](const std::string& p) { return flight::offboard_config_table().reference(p); },
     [](const Making& m) { return flight::make_offboard(m.config, m.origin); }},
}};

/// The rows are the table's, in its order: a module named in one and not the other fails the build.
constexpr bool rows_follow_the_table() {
  for (size_t i = 0; i < kRows.size(); ++i) {
    if (kRows[i].name != kModuleKinds[i].name) return false;
  }
  return true;
}
static_assert(rows_follow_the_table(), "modules/registry.cc: kRows must list modules/module_table.h's modules");

Result<std::unique_ptr<Module>> make_module(const std::string& name, const Making& making) {
  for (const auto& row : kRows) {
    if (row.name == name) return row.make(making);
  }
  return Error{"--modules: unknown module '" + name + "' (known: " + known_modules() + ")"};
}

}  // namespace

std::string config_reference() {
  std::string out;
  for (const auto& row : kRows) {
    const std::string name(row.name);
    out += (out.empty() ? "### " : "\n### ") + name + "\n\n" + row.reference(name + ".");
  }
  return out;
}

Result<std::vector<std::unique_ptr<Module>>> load_modules(const std::string& list, const std::string& config_path,
                                                          const InputChannels& inputs,
                                                          std::vector<std::string>& notes) {
  YAML::Node config;
  std::string config_dir = ".";
  if (!config_path.empty()) {
    auto root = config::load_yaml(config_path, "module config");
    if (!root) return root.error();
    config = *root;
    if (!config.IsNull() && !config.IsMap()) return Error{config_path + ":1: expected a map of module name: settings"};
    config_dir = std::filesystem::path(config_path).parent_path().string();
    if (config_dir.empty()) config_dir = ".";
  }
  if (config.IsMap()) {
    for (const auto& kv : config) {
      if (!kv.first.IsScalar()) {
        return Error{line_of(config_path, kv.first.Mark()) + ": expected a module name (" + known_modules() + ")"};
      }
      const std::string& key = kv.first.Scalar();
      if (!is_module(key)) {
        return Error{line_of(config_path, kv.first.Mark()) + ": unknown module '" + key + "' (known: " +
                     known_modules() + ")"};
      }
    }
  }
  std::vector<std::unique_ptr<Module>> modules;
  std::stringstream names(list);
  for (std::string name; std::getline(names, name, ',');) {
    if (name.empty()) continue;
    const YAML::Node node = config.IsMap() ? config[name] : YAML::Node();
    try {
      const std::string origin = config_path.empty() ? "--config" : config_path;
      auto m = make_module(name, Making{node, origin, config_dir, inputs, notes});
      if (!m) return m.error();
      modules.push_back(std::move(*m));
    } catch (const YAML::Exception& e) {
      // A value of the wrong kind that a module's reader did not expect: one line, never a crash.
      return Error{(config_path.empty() ? std::string("--config") : config_path) + ":" +
                   std::to_string(e.mark.line + 1) + ": " + name + ": " + e.msg};
    }
  }
  return modules;
}

}  // namespace driftlab::modules
