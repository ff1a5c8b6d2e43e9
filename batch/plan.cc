#include "batch/plan.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "modules/module_table.h"

namespace driftlab::batch {
namespace {

using modules::is_module;

std::string canonical_number(double v) {
  if (v == 0) return "0";  // no "-0"
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  double back = 0;
  std::from_chars(buf, buf + std::strlen(buf), back);
  // The shortest text that reads back as the 12-digit value.
  for (int digits = 1; digits <= 17; ++digits) {
    char shorter[32];
    std::snprintf(shorter, sizeof(shorter), "%.*g", digits, back);
    double again = 0;
    std::from_chars(shorter, shorter + std::strlen(shorter), again);
    if (again == back) return shorter;
  }
  return buf;
}

uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (const char c : s) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  return h;
}

}  // namespace

Value Value::of_number(double v) { return {Kind::kNumber, v, canonical_number(v)}; }
Value Value::of_string(std::string s) { return {Kind::kString, 0, std::move(s)}; }
Value Value::of_bool(bool b) { return {Kind::kBool, 0, b ? "true" : "false"}; }

nlohmann::json Value::json() const {
  if (kind == Kind::kNumber) return std::stod(text);
  if (kind == Kind::kBool) return text == "true";
  return text;
}

const char* stage_name(Stage s) {
  switch (s) {
    case Stage::kSim: return "sim";
    case Stage::kReplay: return "replay";
    case Stage::kDiagnose: return "diagnose";
    case Stage::kEval: return "eval";
    case Stage::kReport: return "report";
  }
  return "?";
}

bool Spec::has(Stage st) const { return std::find(stages.begin(), stages.end(), st) != stages.end(); }

const Value* Point::get(const std::string& key) const {
  for (const auto& [k, v] : params) {
    if (k == key) return &v;
  }
  return nullptr;
}

std::vector<Point> expand(const Spec& spec) {
  // What every point shares: the resolved spec without `vary` (and for batches, without the list of logs).
  nlohmann::json base = to_json(Plan{spec, {}})["spec"];
  base.erase("vary");
  base.erase("file");
  base.erase("name");
  base.erase("keep_logs");
  base.erase("logs");  // each log is a point's own value
  const std::string base_text = base.dump();

  std::vector<std::vector<std::pair<std::string, Value>>> combos(1);
  if (!spec.logs.empty()) {  // one point per log (and per combination of the varied values)
    combos.clear();
    for (const auto& l : spec.logs) combos.push_back({{"log", Value::of_string(l)}});
  }
  for (const auto& p : spec.vary) {
    std::vector<std::vector<std::pair<std::string, Value>>> next;
    for (const auto& c : combos) {
      for (const auto& v : p.values) {
        auto d = c;
        d.emplace_back(p.key, v);
        next.push_back(std::move(d));
      }
    }
    combos = std::move(next);
  }
  std::vector<Point> points;
  for (auto& c : combos) {
    auto sorted = c;
    std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::string key = base_text;
    for (const auto& [k, v] : sorted) key += "\n" + k + "=" + v.text;
    char id[17];
    std::snprintf(id, sizeof(id), "%016llx", static_cast<unsigned long long>(fnv1a(key)));
    points.push_back({std::string(id, 12), std::move(c)});
  }
  return points;
}

namespace {

/// One module's settings as a YAML map; a dotted key (`2d.loop_radius`) goes into the map of its section.
void emit_settings(YAML::Emitter& e, const std::map<std::string, Value>& settings) {
  e << YAML::BeginMap;
  for (auto it = settings.begin(); it != settings.end();) {
    const size_t dot = it->first.find('.');
    if (dot == std::string::npos) {
      e << YAML::Key << it->first << YAML::Value;
      if (it->second.kind == Value::Kind::kString) {
        e << YAML::DoubleQuoted << it->second.text;
      } else {
        e << it->second.text;
      }
      ++it;
      continue;
    }
    // The keys of a section are adjacent in the map's order.
    const std::string section = it->first.substr(0, dot + 1);
    std::map<std::string, Value> inner;
    for (; it != settings.end() && it->first.rfind(section, 0) == 0; ++it)
      inner[it->first.substr(dot + 1)] = it->second;
    e << YAML::Key << section.substr(0, dot) << YAML::Value;
    emit_settings(e, inner);
  }
  e << YAML::EndMap;
}

}  // namespace

std::string module_config_yaml(const Spec& spec, const Point& point) {
  auto settings = spec.settings;
  for (const auto& [k, v] : point.params) {
    const size_t dot = k.find('.');
    if (dot != std::string::npos && is_module(k.substr(0, dot))) settings[k.substr(0, dot)][k.substr(dot + 1)] = v;
  }
  if (settings.empty()) return "";
  YAML::Emitter e;
  e << YAML::BeginMap;
  for (const auto& [module, kv] : settings) {
    e << YAML::Key << module << YAML::Value;
    emit_settings(e, kv);
  }
  e << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

std::string faults_yaml(const Spec& spec, const Point& point) {
  auto faults = spec.faults;
  bool varied = false;
  for (const auto& [k, v] : point.params) {
    if (k.rfind("faults.", 0) != 0) continue;
    const size_t dot = k.rfind('.');
    faults[k.substr(7, dot - 7)][k.substr(dot + 1)] = v.number;
    varied = true;
  }
  if (!spec.faults_given && !varied) return "";
  std::ostringstream out;
  out << "# written by driftlab sweep\nstreams:\n";
  if (faults.empty()) return "streams: {}\n";
  for (const auto& [channel, fields] : faults) {
    out << "  " << channel << ":\n";
    for (const auto& [f, v] : fields) out << "    " << f << ": " << canonical_number(v) << "\n";
  }
  return out.str();
}

std::string restamp_of(const Spec& spec, const Point& point) {
  const Value* v = point.get("restamp");
  return v != nullptr ? v->text : spec.restamp;
}

nlohmann::json to_json(const Plan& plan) {
  const Spec& s = plan.spec;
  nlohmann::json j;
  nlohmann::json spec = {{"kind", s.kind}, {"file", s.file}, {"name", s.name}, {"scenario", s.scenario},
                         {"logs", s.logs}, {"duration", s.duration}, {"seed", s.seed}, {"faults", s.faults},
                         {"faults_given", s.faults_given}, {"modules", s.modules}, {"restamp", s.restamp},
                         {"gt", s.gt_channel}, {"est", s.est_channel}, {"align", s.align},
                         {"keep_logs", s.keep_logs}};
  nlohmann::json settings = nlohmann::json::object();
  for (const auto& [m, kv] : s.settings) {
    for (const auto& [k, v] : kv) settings[m][k] = {{"kind", static_cast<int>(v.kind)}, {"text", v.text}};
  }
  spec["settings"] = settings;
  spec["stages"] = nlohmann::json::array();
  for (Stage st : s.stages) spec["stages"].push_back(stage_name(st));
  spec["vary"] = nlohmann::json::array();
  for (const auto& p : s.vary) {
    nlohmann::json values = nlohmann::json::array();
    for (const auto& v : p.values) values.push_back({{"kind", static_cast<int>(v.kind)}, {"text", v.text}});
    spec["vary"].push_back({{"key", p.key}, {"values", values}});
  }
  j["spec"] = spec;
  j["points"] = nlohmann::json::array();
  for (const auto& pt : plan.points) {
    nlohmann::json params = nlohmann::json::array();
    for (const auto& [k, v] : pt.params) params.push_back({{"key", k}, {"kind", static_cast<int>(v.kind)}, {"text", v.text}});
    j["points"].push_back({{"id", pt.id}, {"params", params}});
  }
  return j;
}

Result<Plan> plan_from_json(const nlohmann::json& j, const std::string& origin) {
  auto value = [](const nlohmann::json& v) {
    const auto kind = static_cast<Value::Kind>(v.at("kind").get<int>());
    const std::string text = v.at("text");
    if (kind == Value::Kind::kNumber) return Value::of_number(std::stod(text));
    if (kind == Value::Kind::kBool) return Value::of_bool(text == "true");
    return Value::of_string(text);
  };
  try {
    Plan plan;
    Spec& s = plan.spec;
    const auto& js = j.at("spec");
    s.kind = js.at("kind");
    s.file = js.at("file");
    s.name = js.at("name");
    s.scenario = js.at("scenario");
    s.logs = js.at("logs").get<std::vector<std::string>>();
    s.duration = js.at("duration");
    s.seed = js.at("seed");
    s.faults = js.at("faults").get<std::map<std::string, std::map<std::string, double>>>();
    s.faults_given = js.at("faults_given");
    s.modules = js.at("modules");
    s.restamp = js.at("restamp");
    s.gt_channel = js.at("gt");
    s.est_channel = js.at("est");
    s.align = js.at("align");
    s.keep_logs = js.at("keep_logs");
    for (const auto& [m, kv] : js.at("settings").items()) {
      for (const auto& [k, v] : kv.items()) s.settings[m][k] = value(v);
    }
    for (const auto& st : js.at("stages")) {
      const std::string n = st;
      for (Stage x : {Stage::kSim, Stage::kReplay, Stage::kDiagnose, Stage::kEval, Stage::kReport}) {
        if (n == stage_name(x)) s.stages.push_back(x);
      }
    }
    for (const auto& p : js.at("vary")) {
      Parameter param{p.at("key"), {}};
      for (const auto& v : p.at("values")) param.values.push_back(value(v));
      s.vary.push_back(std::move(param));
    }
    for (const auto& pt : j.at("points")) {
      Point point{pt.at("id"), {}};
      for (const auto& p : pt.at("params")) point.params.emplace_back(p.at("key"), value(p));
      plan.points.push_back(std::move(point));
    }
    return plan;
  } catch (const nlohmann::json::exception& e) {
    return Error{origin + ": not a driftlab sweep plan (" + std::string(e.what()) + ")"};
  }
}

}  // namespace driftlab::batch
