#include "modules/settings.h"

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
#include "slam/slam_module.h"

namespace driftlab::modules {
namespace {

std::string line_of(const std::string& file, const YAML::Mark& mark) {
  return file + ":" + std::to_string(mark.line + 1);
}

/// A parse's outcome without its value.
template <typename T>
Status parsed(const Result<T>& r) {
  return r ? Status{} : Status{r.error()};
}

/// A controller's settings checked: the route a scenario gives stands in for that scenario's (read when the module
/// is made).
Status check_controller(const YAML::Node& config, const ModuleSettings& settings) {
  auto scenario = controller_scenario(config, settings);
  if (!scenario) return scenario.error();
  controller::ControllerConfig base;
  if (scenario->from_scenario) base.route = {{0, 0}, {1, 0}};
  return parsed(controller::parse_controller_config(config, settings.origin, std::move(base)));
}

/// A row of modules/module_table.h with its settings: their reference (the keys with the module's name in front)
/// and their check.
struct SettingsRow {
  std::string_view name;
  std::string (*reference)(const std::string& prefix);
  Status (*check)(const YAML::Node& config, const ModuleSettings& settings);
};

constexpr std::array<SettingsRow, kModuleKinds.size()> kRows{{
    {"slam", [](const std::string& p) { return slam::slam_config_table().reference(p); },
     [](const YAML::Node& c, const ModuleSettings& s) {
       return parsed(slam::slam_config_table().parse(config::Value(c, s.origin, "slam")));
     }},
    {"estimator", [](const std::string& p) { return estimator::estimator_config_table().reference(p); },
     [](const YAML::Node& c, const ModuleSettings& s) {
       return parsed(estimator::parse_estimator_config(c, s.origin));
     }},
    {"controller", [](const std::string& p) { return controller::controller_config_table().reference(p); },
     check_controller},
    {"drone_estimator", [](const std::string& p) { return estimator::drone_estimator_config_table().reference(p); },
     [](const YAML::Node& c, const ModuleSettings& s) {
       return parsed(estimator::drone_estimator_config_table().parse(config::Value(c, s.origin, "drone_estimator")));
     }},
    {"flight", [](const std::string& p) { return flight::flight_config_table().reference(p); },
     [](const YAML::Node& c, const ModuleSettings& s) {
       return parsed(flight::flight_config_table().parse(config::Value(c, s.origin, "flight")));
     }},
    {"offboard", [](const std::string& p) { return flight::offboard_config_table().reference(p); },
     [](const YAML::Node& c, const ModuleSettings& s) {
       return parsed(flight::offboard_config_table().parse(config::Value(c, s.origin, "offboard")));
     }},
}};

/// The rows are the table's, in its order: a module named in one and not the other fails the build.
constexpr bool rows_follow_the_table() {
  for (size_t i = 0; i < kRows.size(); ++i) {
    if (kRows[i].name != kModuleKinds[i].name) return false;
  }
  return true;
}
static_assert(rows_follow_the_table(), "modules/settings.cc: kRows must list modules/module_table.h's modules");

/// The config's top-level keys: each a module.
Result<ModuleSettings> checked(ModuleSettings s) {
  if (!s.root.IsNull() && !s.root.IsMap()) return Error{s.origin + ":1: expected a map of module name: settings"};
  if (s.root.IsMap()) {
    for (const auto& kv : s.root) {
      if (!kv.first.IsScalar()) {
        return Error{line_of(s.origin, kv.first.Mark()) + ": expected a module name (" + known_modules() + ")"};
      }
      const std::string& key = kv.first.Scalar();
      if (!is_module(key)) {
        return Error{line_of(s.origin, kv.first.Mark()) + ": unknown module '" + key + "' (known: " + known_modules() +
                     ")"};
      }
    }
  }
  return s;
}

}  // namespace

YAML::Node ModuleSettings::of(const std::string& module) const {
  if (!root.IsMap()) return YAML::Node();
  YAML::Node map = root;  // a const node's [] of a missing key is invalid; a node's is undefined, as a module expects
  return map[module];
}

Result<ModuleSettings> read_module_settings(const std::string& path) {
  ModuleSettings s;
  if (path.empty()) return s;
  auto root = config::load_yaml(path, "module config");
  if (!root) return root.error();
  s.root = *root;
  s.origin = path;
  s.dir = std::filesystem::path(path).parent_path().string();
  if (s.dir.empty()) s.dir = ".";
  return checked(std::move(s));
}

Result<ModuleSettings> parse_module_settings(const std::string& text, const std::string& origin) {
  ModuleSettings s;
  auto root = config::parse_yaml(text, origin);
  if (!root) return root.error();
  s.root = *root;
  s.origin = origin;
  return checked(std::move(s));
}

Status for_each_module(const ModuleSettings& settings, const std::string& modules,
                       const std::function<Status(const std::string& name, const YAML::Node& config)>& fn) {
  std::stringstream names(modules);
  for (std::string name; std::getline(names, name, ',');) {
    if (name.empty()) continue;
    if (!is_module(name)) return Error{"--modules: unknown module '" + name + "' (known: " + known_modules() + ")"};
    try {
      if (Status s = fn(name, settings.of(name)); !s) return s;
    } catch (const YAML::Exception& e) {
      // A value of the wrong kind that a module's reader did not expect: one line, never a crash.
      return Error{settings.origin + ":" + std::to_string(e.mark.line + 1) + ": " + name + ": " + e.msg};
    }
  }
  return {};
}

Status check_module_settings(const ModuleSettings& settings, const std::string& modules) {
  return for_each_module(settings, modules, [&](const std::string& name, const YAML::Node& config) {
    const auto row = std::find_if(kRows.begin(), kRows.end(), [&](const SettingsRow& r) { return r.name == name; });
    return row->check(config, settings);  // every module has its row (rows_follow_the_table)
  });
}

std::string config_reference() {
  std::string out;
  for (const auto& row : kRows) {
    const std::string name(row.name);
    out += (out.empty() ? "### " : "\n### ") + name + "\n\n" + row.reference(name + ".");
  }
  return out;
}

Result<ControllerScenario> controller_scenario(const YAML::Node& config, const ModuleSettings& settings) {
  ControllerScenario out;
  if (config.IsMap() && config["scenario"].IsDefined()) {
    const YAML::Node node = config["scenario"];
    if (!node.IsScalar()) {
      return Error{line_of(settings.origin, node.Mark()) + ": controller.scenario: expected a file name"};
    }
    out.path = node.Scalar();
    if (!out.path.empty() && out.path[0] != '/') out.path = (std::filesystem::path(settings.dir) / out.path).string();
    out.from_scenario = !out.path.empty();
  } else if (!(config.IsMap() && config["route"].IsDefined())) {
    out.from_scenario = true;  // the default scenario
  }
  return out;
}

}  // namespace driftlab::modules
