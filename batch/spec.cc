#include "batch/spec.h"

#include <fnmatch.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <sstream>

#include "core/config.h"
#include "core/install_layout.h"
#include "faults/faults.h"
#include "modules/module_table.h"
#include "modules/settings.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

using modules::is_module;
using modules::known_modules;

/// "FILE:LINE: KEY" for messages.
std::string where(const std::string& file, const YAML::Node& node, const std::string& key) {
  return file + ":" + std::to_string(node.Mark().line + 1) + ": " + key;
}

/// A YAML scalar as a typed value: numbers first (as YAML reads them), then true/false, else a string.
Value scalar_value(const YAML::Node& n) {
  const std::string& s = n.Scalar();
  if (n.Tag() != "!") {  // not quoted
    double d = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), d);
    if (r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(d)) return Value::of_number(d);
    if (s == "true" || s == "false") return Value::of_bool(s == "true");
  }
  return Value::of_string(s);
}

std::string absolute(const std::string& path, const fs::path& base) {
  fs::path p(path);
  if (p.is_relative()) p = base / p;
  return p.lexically_normal().string();
}

Status check_stage_order(const Spec& s, const std::string& at) {
  if (s.has(Stage::kSim) && !s.logs.empty()) return Error{at + ": sim with logs: a sweep runs a scenario or logs"};
  if (!s.has(Stage::kSim) && s.logs.empty()) return Error{at + ": no sim stage and no logs: nothing to work on"};
  if (s.has(Stage::kReplay) && s.modules.empty()) return Error{at + ": replay needs `modules:` (slam, estimator, ...)"};
  return {};
}

Result<Parameter> read_parameter(const std::string& file, const std::string& key, const YAML::Node& n) {
  Parameter p{key, {}};
  const std::string here = where(file, n, "vary: " + key);
  if (n.IsSequence()) {
    for (const auto& v : n) {
      if (!v.IsScalar()) return Error{here + ": values must be scalars (numbers, words)"};
      p.values.push_back(scalar_value(v));
    }
  } else if (n.IsMap()) {
    double from = 0, to = 0, step = 0;
    int64_t count = 0;
    std::set<std::string> seen;
    for (const auto& kv : n) {
      const std::string k = kv.first.Scalar();
      seen.insert(k);
      if (k != "from" && k != "to" && k != "step" && k != "count") {
        return Error{here + ": unknown grid key '" + k + "' (a grid is {from, to, step} or {from, to, count})"};
      }
      const Value v = kv.second.IsScalar() ? scalar_value(kv.second) : Value{};
      if (v.kind != Value::Kind::kNumber) return Error{here + ": grid " + k + " must be a number"};
      if (k == "from") from = v.number;
      if (k == "to") to = v.number;
      if (k == "step") step = v.number;
      if (k == "count") {
        if (v.number != std::floor(v.number)) return Error{here + ": grid count must be a whole number"};
        count = static_cast<int64_t>(v.number);
      }
    }
    if (!seen.count("from") || !seen.count("to") || seen.count("step") == seen.count("count")) {
      return Error{here + ": a grid is {from, to, step} or {from, to, count}"};
    }
    if (seen.count("step")) {
      if (!(step > 0)) return Error{here + ": grid step must be positive"};
      if (to < from) return Error{here + ": empty grid (to < from)"};
      const double n_steps = std::floor((to - from) / step + 1e-9);
      if (n_steps > 10000) return Error{here + ": grid of more than 10,000 values"};
      for (int64_t i = 0; i <= static_cast<int64_t>(n_steps); ++i)
        p.values.push_back(Value::of_number(from + i * step));
    } else {
      if (count < 1) return Error{here + ": empty grid (count < 1)"};
      if (count > 10000) return Error{here + ": grid of more than 10,000 values"};
      for (int64_t i = 0; i < count; ++i) {
        p.values.push_back(Value::of_number(count == 1 ? from : from + (to - from) * i / (count - 1)));
      }
    }
  } else {
    return Error{here + ": expected a list of values or a grid {from, to, step}"};
  }
  if (p.values.empty()) return Error{here + ": empty list of values"};
  std::set<std::string> distinct;
  for (const auto& v : p.values) {
    if (!distinct.insert(v.text).second) return Error{here + ": value " + v.text + " given twice"};
  }
  return p;
}

/// Checks a parameter's key and its values' types against what the point can do with them.
Status check_parameter(const std::string& file, const YAML::Node& node, const Parameter& p, const Spec& s,
                       const std::set<std::string>& scenario_channels) {
  const std::string here = where(file, node, "vary: " + p.key);
  auto all = [&](Value::Kind k) {
    return std::all_of(p.values.begin(), p.values.end(), [k](const Value& v) { return v.kind == k; });
  };
  if (p.key == "seed") {
    for (const auto& v : p.values) {
      if (v.kind != Value::Kind::kNumber || v.number < 0 || v.number != std::floor(v.number) || v.number > 9e15) {
        return Error{here + ": " + v.text + " is not a non-negative whole number"};
      }
    }
    return {};
  }
  if (p.key == "duration") {
    if (!s.has(Stage::kSim)) return Error{here + ": duration is the simulation's; this sweep has no sim stage"};
    for (const auto& v : p.values) {
      if (v.kind != Value::Kind::kNumber || !(v.number > 0))
        return Error{here + ": " + v.text + " is not a positive number"};
    }
    return {};
  }
  if (p.key == "restamp") {
    if (!s.has(Stage::kReplay)) return Error{here + ": restamp is the replay's; this sweep has no replay stage"};
    for (const auto& v : p.values) {
      if (v.text != "none" && v.text != "auto") return Error{here + ": " + v.text + " is neither none nor auto"};
    }
    return {};
  }
  const size_t dot = p.key.find('.');
  const std::string head = p.key.substr(0, dot);
  if (head == "faults") {
    const size_t dot2 = p.key.rfind('.');
    if (dot == std::string::npos || dot2 == dot) {
      return Error{here + ": a fault is addressed as faults.CHANNEL.FIELD (e.g. faults.IMU.clock_offset_s)"};
    }
    if (!s.has(Stage::kSim) && !s.has(Stage::kReplay)) {
      return Error{here + ": faults need a sim stage (--faults) or a replay stage (--inject)"};
    }
    const std::string channel = p.key.substr(dot + 1, dot2 - dot - 1), field = p.key.substr(dot2 + 1);
    if (s.has(Stage::kSim) && !scenario_channels.empty() && !scenario_channels.count(channel)) {
      std::string known;
      for (const auto& c : scenario_channels) known += (known.empty() ? "" : ", ") + c;
      return Error{here + ": the scenario publishes no channel " + channel + " (it has " + known + ")"};
    }
    if (!all(Value::Kind::kNumber)) return Error{here + ": fault values must be numbers"};
    // The fault model's own parser checks the field and each value's range.
    for (const auto& v : p.values) {
      const std::string yaml = "streams:\n  " + channel + ":\n    " + field + ": " + v.text + "\n";
      if (auto f = parse_faults(yaml, "x"); !f) {
        std::string m = f.error().message;
        if (const size_t colon = m.find(": "); colon != std::string::npos) m = m.substr(colon + 2);
        if (const size_t colon = m.find(": "); colon != std::string::npos && m.rfind("x:", 0) == 0)
          m = m.substr(colon + 2);
        // The parser names keys by their place in the YAML above ('streams.IMU.latency_s'); the spec names the field.
        const std::string place = "'streams." + channel + ".";
        if (const size_t at = m.find(place); at != std::string::npos) m.replace(at, place.size(), "'");
        return Error{here + ": " + m};
      }
    }
    return {};
  }
  if (is_module(head)) {
    if (dot == std::string::npos || dot + 1 == p.key.size()) {
      return Error{here + ": a module setting is addressed as MODULE.KEY (e.g. estimator.window_s)"};
    }
    if (!s.has(Stage::kReplay)) return Error{here + ": module settings need a replay stage"};
    return {};  // the modules' tables check the key and values (validate_module_settings)
  }
  return Error{here +
               ": unknown parameter (seed, duration, restamp, faults.CHANNEL.FIELD or MODULE.KEY with "
               "MODULE one of " +
               known_modules() + ")"};
}

/// The channels a scenario publishes (its sensors' `channel`s), for checking faults early; empty when unreadable
/// (the simulator then says what is wrong).
std::set<std::string> scenario_channels(const std::string& path) {
  std::set<std::string> out;
  try {
    const YAML::Node root = YAML::LoadFile(path);
    for (const auto& sensor : root["sensors"]) {
      if (sensor["channel"]) out.insert(sensor["channel"].Scalar());
      if (sensor["tf_channel"]) out.insert(sensor["tf_channel"].Scalar());
    }
  } catch (const YAML::Exception&) {
    out.clear();
  }
  return out;
}

/// The faults section of a scenario (docs/simulator.md) as channel -> field -> value.
std::map<std::string, std::map<std::string, double>> scenario_faults(const std::string& path) {
  std::map<std::string, std::map<std::string, double>> out;
  try {
    const YAML::Node root = YAML::LoadFile(path);
    for (const auto& stream : root["faults"]["streams"]) {
      for (const auto& kv : stream.second) out[stream.first.Scalar()][kv.first.Scalar()] = kv.second.as<double>();
    }
  } catch (const YAML::Exception&) {
    out.clear();
  }
  return out;
}

std::string stage_list(const Spec& s) {
  std::string out;
  for (Stage st : s.stages) out += std::string(out.empty() ? "" : ",") + stage_name(st);
  return out;
}

}  // namespace

bool is_pattern(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

std::vector<std::string> expand_pattern(const std::string& pattern) {
  const fs::path pat(pattern);
  const std::string leaf = pat.filename().string();
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(pat.parent_path().empty() ? "." : pat.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file(ec) && ::fnmatch(leaf.c_str(), name.c_str(), FNM_PERIOD) == 0)
      out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

namespace {

/// "FILE:LINE: KEY: what", as the spec's other messages are.
Error at(const config::Value& v, const std::string& what) { return Error{v.place() + ": " + v.key() + ": " + what}; }

/// A spec file as read: the spec, and the keys whose meaning depends on the others, kept to be read once all are
/// known (a scenario and logs resolved against the spec's folder; the pipeline defaults from the logs and modules;
/// what a parameter may be depends on the stages and the scenario's channels).
struct SpecFile {
  Spec spec;
  std::optional<config::Value> scenario, logs, pipeline, vary;
};

/// A key kept as given, for the spec file's check.
config::Table<SpecFile>& keep(config::Table<SpecFile>& t, const char* key, std::optional<config::Value> SpecFile::*m,
                              const char* type, const char* doc) {
  return t.custom<std::optional<config::Value>>(
      key, m, type, "", "", doc,
      [](const config::Value& v, std::optional<config::Value>& out) -> Status {
        out = v;
        return {};
      },
      [](const std::optional<config::Value>&) { return std::string(); });
}

Status read_modules(const config::Value& v, std::string& out) {
  std::vector<std::string> names;
  const YAML::Node& n = v.node();
  if (n.IsScalar()) {
    std::stringstream ss(n.Scalar());
    for (std::string m; std::getline(ss, m, ',');) {
      m.erase(0, m.find_first_not_of(' '));
      m.erase(m.find_last_not_of(' ') + 1);
      names.push_back(m);
    }
  } else if (n.IsSequence()) {
    for (const auto& m : n) {
      if (!m.IsScalar()) return at(v, "a list of modules (" + known_modules() + ")");
      names.push_back(m.Scalar());
    }
  } else {
    return at(v, "a list of modules (" + known_modules() + ")");
  }
  out.clear();
  for (const auto& m : names) {
    if (!is_module(m)) return at(v, "unknown module '" + m + "' (" + known_modules() + ")");
    out += (out.empty() ? "" : ",") + m;
  }
  return {};
}

Status read_settings(const config::Value& v, std::map<std::string, std::map<std::string, Value>>& out) {
  if (!v.node().IsMap()) return at(v, "one map of settings per module (estimator: {window_s: 0.5})");
  return v.entries([&](const std::string& module, const config::Value& m, const config::Value& key) -> Status {
    if (!is_module(module))
      return Error{key.place() + ": settings: " + module + ": unknown module (" + known_modules() + ")"};
    if (!m.node().IsMap()) return Error{m.place() + ": settings: " + module + ": a map of key: value"};
    // A section's map (slam: {2d: {loop_radius: 2}}) gives dotted keys (2d.loop_radius), as `vary` names them.
    std::function<Status(const config::Value&, const std::string&)> read = [&](const config::Value& map,
                                                                               const std::string& prefix) {
      return map.entries([&](const std::string& name, const config::Value& x, const config::Value&) -> Status {
        if (x.node().IsMap()) return read(x, prefix + name + ".");
        if (!x.node().IsScalar())
          return Error{x.place() + ": settings: " + module + "." + prefix + name + ": expected a single value"};
        out[module][prefix + name] = scalar_value(x.node());
        return {};
      });
    };
    return read(m, "");
  });
}

/// The scenario's `faults:` form (docs/faults.md), checked by the fault model's parser.
Status read_faults(const config::Value& v, std::map<std::string, std::map<std::string, double>>& out) {
  YAML::Emitter e;
  e << v.node();
  if (auto f = parse_faults(std::string(e.c_str()), v.file() + " (faults)"); !f) return at(v, f.error().message);
  for (const auto& stream : v.node()["streams"]) {
    for (const auto& f : stream.second) out[stream.first.Scalar()][f.first.Scalar()] = f.second.as<double>();
  }
  return {};
}

Result<std::vector<Stage>> read_pipeline(const config::Value& v) {
  if (!v.node().IsSequence()) return at(v, "a list of stages (sim, replay, diagnose, eval)");
  std::set<Stage> seen;
  for (const auto& st : v.node()) {
    const std::string n = st.IsScalar() ? st.Scalar() : "";
    const Stage stage = n == "sim"        ? Stage::kSim
                        : n == "replay"   ? Stage::kReplay
                        : n == "diagnose" ? Stage::kDiagnose
                        : n == "eval"     ? Stage::kEval
                                          : Stage::kReport;
    if (stage == Stage::kReport)
      return Error{where(v.file(), st, "pipeline") + ": unknown stage '" + n + "' (sim, replay, diagnose, eval)"};
    seen.insert(stage);
  }
  std::vector<Stage> out;
  for (Stage st : {Stage::kSim, Stage::kReplay, Stage::kDiagnose, Stage::kEval}) {
    if (seen.count(st)) out.push_back(st);
  }
  return out;
}

/// The logs: paths and patterns, relative to the spec's folder.
Status read_logs(const config::Value& v, const fs::path& base, std::vector<std::string>& out) {
  const YAML::Node& n = v.node();
  std::vector<std::string> items;
  if (n.IsScalar()) items.push_back(n.Scalar());
  for (const auto& x : n) {
    if (!x.IsScalar()) return at(v, "a list of logs (paths or globs)");
    items.push_back(x.Scalar());
  }
  if (!n.IsScalar() && !n.IsSequence()) return at(v, "a list of logs (paths or globs)");
  for (const auto& item : items) {
    const std::string p = absolute(item, base);
    if (!is_pattern(p)) {
      if (!fs::is_regular_file(p)) return at(v, "no such log: " + item);
      out.push_back(p);
      continue;
    }
    auto files = expand_pattern(p);
    if (files.empty()) return at(v, item + " matches no file");
    out.insert(out.end(), files.begin(), files.end());
  }
  return {};
}

/// The varied parameters, checked against the stages and the scenario's channels, and their product bounded.
Status read_vary(const config::Value& v, Spec& s) {
  const std::string& path = v.file();
  const std::set<std::string> channels = s.has(Stage::kSim) ? scenario_channels(s.scenario) : std::set<std::string>{};
  if (!v.node().IsMap()) return at(v, "a map of PARAMETER: [values] or {from, to, step}");
  for (const auto& kv : v.node()) {
    const std::string key = kv.first.Scalar();
    for (const auto& p : s.vary) {
      if (p.key == key) return Error{where(path, kv.first, "vary: " + key) + ": given twice"};
    }
    auto p = read_parameter(path, key, kv.second);
    if (!p) return p.error();
    if (auto st = check_parameter(path, kv.first, *p, s, channels); !st) return st;
    s.vary.push_back(std::move(*p));
  }
  // Each grid may hold 10,000 values, and their product is the sweep: two such grids were 10^8 points, all
  // expanded in memory before anything ran.
  uint64_t points = std::max<uint64_t>(1, s.logs.size());
  std::string product = s.logs.empty() ? "" : std::to_string(s.logs.size()) + " logs";
  for (const auto& p : s.vary) {
    points = std::min<uint64_t>(points * p.values.size(), uint64_t{1} << 40);  // each factor is 10,000 at most
    product += (product.empty() ? "" : " x ") + std::to_string(p.values.size());
  }
  if (points > kMaxPoints) {
    return at(v, product + " = " +
                     (points >= (uint64_t{1} << 40) ? std::string("over 10^12") : std::to_string(points)) +
                     " points, more than the " + std::to_string(kMaxPoints) +
                     " a sweep may have: vary fewer values, or split it into several sweeps");
  }
  return {};
}

/// What the spec file's keys mean together: paths resolved, the pipeline given or implied, its stages checked,
/// the parameters read, and the scenario's faults the base of a varied fault.
Status resolve(const config::Value& map, SpecFile& f) {
  Spec& s = f.spec;
  const fs::path base = fs::absolute(fs::path(map.file())).parent_path();
  if (f.scenario) {
    auto text = f.scenario->text();
    if (!text) return text.error();
    s.scenario = absolute(*text, base);
    if (!fs::is_regular_file(s.scenario)) return at(*f.scenario, "no such scenario file: " + s.scenario);
  }
  if (f.logs) {
    if (Status st = read_logs(*f.logs, base, s.logs); !st) return st;
  }
  s.faults_given = map["faults"].given();
  if (f.pipeline && f.pipeline->given()) {
    auto stages = read_pipeline(*f.pipeline);
    if (!stages) return stages.error();
    s.stages = std::move(*stages);
  } else {
    if (s.logs.empty()) s.stages.push_back(Stage::kSim);
    if (!s.modules.empty()) s.stages.push_back(Stage::kReplay);
    s.stages.push_back(Stage::kDiagnose);
    if (!s.modules.empty()) s.stages.push_back(Stage::kEval);
  }
  const std::string& path = map.file();
  if (auto st = check_stage_order(s, path + ": pipeline " + stage_list(s)); !st) return st;
  if (!s.has(Stage::kSim) && s.duration > 0) return Error{path + ": duration: only a simulation has one"};
  if (s.has(Stage::kSim) && s.scenario.empty()) s.scenario = data_path("scenarios/indoor.yaml").string();
  if (f.vary && f.vary->given()) {
    if (Status st = read_vary(*f.vary, s); !st) return st;
  }
  // A faults field varied without `faults:` in the spec starts from the scenario's own faults (sweeps of a
  // scenario), so the other streams keep theirs.
  if (!s.faults_given && s.has(Stage::kSim) &&
      std::any_of(s.vary.begin(), s.vary.end(), [](const Parameter& p) { return p.key.rfind("faults.", 0) == 0; })) {
    s.faults = scenario_faults(s.scenario);
  }
  return {};
}

const config::Table<SpecFile>& spec_table() {
  static const auto table = [] {
    using config::Table;
    Table<Spec> keys;
    keys.text("name", &Spec::name, "the sweep's name")
        .shown_default("the spec file's")
        .number("duration", &Spec::duration, config::above(0), "s", "of each simulation")
        .shown_default("the scenario's")
        .integer("seed", &Spec::seed, config::between(0, 9e15), "", "of each simulation")
        .shown_default("the scenario's")
        .custom<std::map<std::string, std::map<std::string, double>>>(
            "faults", &Spec::faults, "map", "", "", "the faults of each point (the scenario's `faults:` form)",
            read_faults, [](const auto&) { return std::string(); })
        .shown_default("the scenario's")
        .custom<std::string>("modules", &Spec::modules, "list", "", "",
                             "the modules replay hosts (a list, or comma-separated)", read_modules,
                             [](const std::string&) { return std::string(); })
        .shown_default("none")
        .custom<std::map<std::string, std::map<std::string, Value>>>(
            "settings", &Spec::settings, "map", "", "", "module -> key -> value, as replay's --config", read_settings,
            [](const auto&) { return std::string(); })
        .shown_default("the modules' own")
        .choice("restamp", &Spec::restamp, {"none", "auto"}, "replay's --restamp")
        .flag("keep_logs", &Spec::keep_logs, "keep each finished point's sim.lcm and replay.lcm");
    Table<Spec> eval;
    eval.text("gt", &Spec::gt_channel, "the ground-truth channel", config::Text::kNonEmpty)
        .text("est", &Spec::est_channel, "the estimate's channel", config::Text::kNonEmpty)
        .choice("align", &Spec::align, {"none", "se3", "sim3", "posyaw"}, "eval's --align");
    keys.section("eval", eval, "what eval scores");
    Table<SpecFile> t;
    t.describe(
        "A sweep runs a scenario or logs through a pipeline once per point: the product of the values of every "
        "varied parameter (and of the logs). What may be varied: docs/batch.md.");
    keep(t, "scenario", &SpecFile::scenario, "path", "the scenario each point simulates (relative to the spec)")
        .shown_default("the default scenario");
    keep(t, "logs", &SpecFile::logs, "list", "logs, paths or patterns (relative to the spec): a point per log")
        .shown_default("none");
    t.include(&SpecFile::spec, keys);
    keep(t, "pipeline", &SpecFile::pipeline, "list", "the stages: sim, replay, diagnose, eval")
        .shown_default("sim (no logs), replay, diagnose, eval (replay and eval with modules)");
    keep(t, "vary", &SpecFile::vary, "map", "PARAMETER: [values] or {from, to, step} (docs/batch.md)")
        .shown_default("none");
    t.check(resolve);
    return t;
  }();
  return table;
}

}  // namespace

std::string spec_reference() { return spec_table().reference(); }

Result<Spec> load_spec(const std::string& path) {
  auto root = config::load_yaml(path, "sweep spec");
  if (!root) return root.error();
  const config::Value doc(*root, path);
  if (!doc.given() || !root->IsMap())
    return Error{path + ": a sweep spec is a map (" + spec_table().known_keys() + ")"};
  SpecFile f;
  f.spec.file = path;
  f.spec.name = fs::path(path).stem().string();
  if (Status st = spec_table().read(doc, f); !st) return st.error();
  return f.spec;
}

Result<Spec> batch_spec(const std::string& command, const std::vector<std::string>& logs) {
  Spec s;
  s.kind = "batch";
  s.name = "batch " + command;
  if (command == "diagnose") {
    s.stages = {Stage::kDiagnose};
  } else if (command == "eval") {
    s.stages = {Stage::kEval};
  } else if (command == "report") {
    s.stages = {Stage::kDiagnose, Stage::kReport};
  } else {
    return Error{"batch " + command + ": unknown command (diagnose, eval, report)"};
  }
  std::set<std::string> seen;
  for (const auto& l : logs) {
    std::error_code ec;
    const std::string p = fs::absolute(fs::path(l), ec).lexically_normal().string();
    if (!fs::is_regular_file(p, ec)) return Error{l + ": no such log file"};
    if (seen.insert(p).second) s.logs.push_back(p);
  }
  if (s.logs.empty()) return Error{"batch " + command + ": no logs given"};
  return s;
}

Status validate_module_settings(const Spec& spec) {
  std::vector<const Parameter*> module_params;
  for (const auto& p : spec.vary) {
    const size_t dot = p.key.find('.');
    if (dot != std::string::npos && is_module(p.key.substr(0, dot))) module_params.push_back(&p);
  }
  if (spec.settings.empty() && module_params.empty()) return {};
  auto check = [&](const Point& pt) -> Status {
    auto settings = modules::parse_module_settings(module_config_yaml(spec, pt), "settings");
    return settings ? modules::check_module_settings(*settings, spec.modules) : Status{settings.error()};
  };
  size_t rounds = 1;
  for (const auto* p : module_params) rounds = std::max(rounds, p->values.size());
  for (size_t i = 0; i < rounds; ++i) {
    Point pt;
    for (const auto* p : module_params) pt.params.emplace_back(p->key, p->values[i % p->values.size()]);
    const Status checked = check(pt);
    if (checked) continue;
    // Name the spec's key refused: the fixed settings when they are refused on their own, else the first varied
    // value refused with them alone (none alone: the values together, named as the settings).
    std::string key = "settings";
    if (check(Point{})) {
      for (const auto& [k, v] : pt.params) {
        if (!check(Point{"", {{k, v}}})) {
          key = "vary: " + k + " = " + v.text;
          break;
        }
      }
    }
    return Error{spec.file + ": " + key + ": the modules refuse it: " + checked.message()};
  }
  return {};
}

}  // namespace driftlab::batch
