// Sweeps and batches of driftlab's commands (docs/batch.md): a spec (YAML) names a scenario or logs, the parameters
// to vary and the pipeline per point; it expands into points, each with an id that depends only on what the point
// computes, so the same point keeps its id (and its finished results) across runs. A Plan is the resolved spec and
// its points, stored as DIR/plan.json so that a task on any node that sees DIR runs exactly the point it was given.
// Reading a spec file is batch/spec.h's; this header is what a spec is, its points and each point's files.
// Thread-safety: plain values and pure functions.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/result.h"

namespace driftlab::batch {

/// One value of a parameter: a number, a string or a bool, with its canonical text (numbers: shortest text that
/// reads back the same, at most 12 significant digits, so a grid's 0.15 is "0.15", not 0.15000000000000002).
struct Value {
  enum class Kind { kNumber, kString, kBool };
  Kind kind = Kind::kString;
  double number = 0;
  std::string text;

  static Value of_number(double v);
  static Value of_string(std::string s);
  static Value of_bool(bool b);
  nlohmann::json json() const;
};

/// What a sweep may vary, by key (docs/batch.md):
///   seed, duration                      the simulation's (sweeps of a scenario)
///   restamp                             none | auto (driftlab replay --restamp)
///   faults.CHANNEL.FIELD                a fault field of docs/faults.md on one channel
///   MODULE.KEY                          a module setting (modules/module_table.h), written into replay's --config
struct Parameter {
  std::string key;
  std::vector<Value> values;
};

/// The stages a point runs, in this order.
enum class Stage { kSim, kReplay, kDiagnose, kEval, kReport };
const char* stage_name(Stage s);

/// A resolved spec: paths absolute, globs expanded, every key checked.
struct Spec {
  std::string kind = "sweep";  ///< "sweep" or "batch"
  std::string file;            ///< the spec file (for messages); empty for a batch
  std::string name;
  std::string scenario;        ///< absolute; empty: the default scenario (sweeps over a simulation)
  std::vector<std::string> logs;  ///< absolute (sweeps over logs, and batches: one point per log)
  double duration = 0;         ///< [s]; 0: the scenario's
  int64_t seed = -1;           ///< -1: the scenario's
  /// Base faults by channel, field -> value (the scenario's own when the spec gives none and nothing is varied).
  std::map<std::string, std::map<std::string, double>> faults;
  bool faults_given = false;   ///< the spec has `faults:` (replacing the scenario's)
  std::string modules;         ///< replay modules, comma-separated
  /// Module settings (the --config file): module -> key -> value (YAML scalar text, typed).
  std::map<std::string, std::map<std::string, Value>> settings;
  std::string restamp = "none";  ///< none | auto
  std::string gt_channel = "GROUND_TRUTH";
  std::string est_channel = "EKF_ODOM";
  std::string align = "posyaw";
  bool keep_logs = true;       ///< keep sim.lcm and replay.lcm of a finished point
  std::vector<Stage> stages;
  std::vector<Parameter> vary;

  bool has(Stage s) const;
};

/// One point: its id and its parameter values in the spec's order; over logs, "log" (the path) comes first.
struct Point {
  std::string id;
  std::vector<std::pair<std::string, Value>> params;
  const Value* get(const std::string& key) const;
};

struct Plan {
  Spec spec;
  std::vector<Point> points;
};

/// The points of a spec: the cartesian product of the logs (if any) and `vary` in the order given, each with a
/// stable id (12 hex digits of a 64-bit FNV-1a hash of what the point computes: the resolved spec without `vary`,
/// the logs and the name, and the point's values), so a point keeps its id when the grid around it grows.
std::vector<Point> expand(const Spec& spec);

/// The most points a sweep spec may expand to (the product of its grids and lists, and its logs).
constexpr uint64_t kMaxPoints = 100'000;

/// The module settings file (YAML, one map per module) of a point: the spec's settings with the point's varied
/// module keys set. Empty when there is nothing to set.
std::string module_config_yaml(const Spec& spec, const Point& point);
/// The fault description (YAML, docs/faults.md) of a point; empty when the spec neither gives nor varies faults.
std::string faults_yaml(const Spec& spec, const Point& point);
/// The restamp of a point: the spec's, or its varied value.
std::string restamp_of(const Spec& spec, const Point& point);

nlohmann::json to_json(const Plan& plan);
Result<Plan> plan_from_json(const nlohmann::json& j, const std::string& origin);

}  // namespace driftlab::batch
