// A module config (`driftlab replay|run --config FILE`, a sweep's settings: a map of module name -> settings,
// docs/replay.md) read and checked against the modules' config tables without making any module. The registry
// (modules/registry.h) makes the modules from what is read here; a sweep checks its settings with it before any
// point runs. Light to link: the tables, not the modules' code (no SLAM, simulator or flight stack), so the
// `driftlab` program checks a sweep's settings in-process. Thread-safety: pure functions.
#pragma once

#include <yaml-cpp/yaml.h>

#include <functional>
#include <string>

#include "core/result.h"
#include "modules/module_table.h"

namespace driftlab::modules {

/// A module config as read: its YAML (null when there is no file), what its messages name (the file, or
/// "--config" when there is none) and the folder its relative paths start from.
struct ModuleSettings {
  YAML::Node root;
  std::string origin = "--config";
  std::string dir = ".";
  /// One module's settings: its map, or an undefined node (its defaults).
  YAML::Node of(const std::string& module) const;
};

/// Reads the config file at `path` ("" for none: every module with its defaults) and checks that it is a map whose
/// keys are modules of module_table.h. Errors are one line naming the file and line.
Result<ModuleSettings> read_module_settings(const std::string& path);
/// The same from YAML text, its messages naming `origin`, its relative paths starting in the current folder.
Result<ModuleSettings> parse_module_settings(const std::string& text, const std::string& origin);

/// Checks the settings of each module named in `modules` (comma-separated) against its table: every key known,
/// every value of its type and in its range, the files it names there; the first problem as one line naming the
/// file, line and key, as making the module would say it. What a module reads only when it is made (the scenario
/// a controller takes its route from) is not read.
Status check_module_settings(const ModuleSettings& settings, const std::string& modules);

/// Calls fn with each module named in `modules` (comma-separated) and its settings, in that order, until one fails.
/// A name not in module_table.h is an error ("--modules: unknown module ..."), as is a value of a kind a module's
/// reader did not expect (yaml-cpp throws): one line naming the config, its line and the module.
Status for_each_module(const ModuleSettings& settings, const std::string& modules,
                       const std::function<Status(const std::string& name, const YAML::Node& config)>& fn);

/// The reference of the module config: every module's keys with type, unit, default, range and description, as
/// markdown (from the modules' config tables, core/config.h), in module_table.h's order.
std::string config_reference();

/// Where a controller's defaults come from: the scenario its settings name (relative to the config's folder), the
/// default scenario (`path` empty) when they give no route, or none (`from_scenario` false) when they give a route
/// and no scenario.
struct ControllerScenario {
  bool from_scenario = false;
  std::string path;
};
Result<ControllerScenario> controller_scenario(const YAML::Node& config, const ModuleSettings& settings);

}  // namespace driftlab::modules
