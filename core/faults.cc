#include "core/faults.h"
#include "core/internal/faults_yaml.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <utility>

namespace driftlab {
namespace {

std::string at(const std::string& origin, const YAML::Node& node) {
  return origin + ":" + std::to_string(node.Mark().line + 1);
}

/// The keys of a stream's faults, with where each goes and its valid range.
struct Key {
  const char* name;
  double StreamFaults::*field;
  double min, max;
};
constexpr Key kKeys[] = {
    {"clock_offset_s", &StreamFaults::clock_offset_s, -1e6, 1e6},
    {"clock_drift_ppm", &StreamFaults::clock_drift_ppm, -1e5, 1e5},
    {"latency_s", &StreamFaults::latency_s, 0, 1e3},
    {"jitter_s", &StreamFaults::jitter_s, 0, 1e3},
    {"drop_probability", &StreamFaults::drop_probability, 0, 1},
    {"burst_enter", &StreamFaults::burst_enter, 0, 1},
    {"burst_exit", &StreamFaults::burst_exit, 0, 1},
    {"duplicate_probability", &StreamFaults::duplicate_probability, 0, 1},
    {"reorder_probability", &StreamFaults::reorder_probability, 0, 1},
    {"reorder_delay_s", &StreamFaults::reorder_delay_s, 0, 1e3},
};

std::string known_keys() {
  std::string out;
  for (const Key& k : kKeys) out += (out.empty() ? "" : ", ") + std::string(k.name);
  return out;
}

driftlab::fault_t fault(const std::string& channel, const char* kind, int64_t start, int64_t end,
                        std::vector<std::pair<std::string, double>> params, std::vector<int64_t> affected = {}) {
  driftlab::fault_t f;
  f.channel = channel;
  f.kind = kind;
  f.start_utime = start;
  f.end_utime = end;
  for (auto& [name, value] : params) {
    f.param_names.push_back(name);
    f.param_values.push_back(value);
  }
  f.nparams = static_cast<int32_t>(f.param_names.size());
  f.affected_seq = std::move(affected);
  f.naffected = static_cast<int32_t>(f.affected_seq.size());
  return f;
}

}  // namespace

Result<FaultConfig> parse_faults(const std::string& text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return Error{origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
  return parse_faults(root, origin);
}

Result<FaultConfig> parse_faults(const YAML::Node& root, const std::string& origin) {
  FaultConfig config;
  if (!root || root.IsNull()) return config;
  if (!root.IsMap()) return Error{at(origin, root) + ": expected a map with 'seed' and 'streams'"};
  for (const auto& top : root) {
    const std::string key = top.first.as<std::string>();
    if (key == "seed") {
      try {
        config.seed = top.second.as<uint64_t>();
      } catch (const YAML::Exception&) {
        return Error{at(origin, top.second) + ": seed must be a non-negative integer"};
      }
    } else if (key == "streams") {
      if (!top.second.IsMap()) return Error{at(origin, top.second) + ": 'streams' must map channels to faults"};
      for (const auto& stream : top.second) {
        const std::string channel = stream.first.as<std::string>();
        if (!stream.second.IsMap()) {
          return Error{at(origin, stream.second) + ": faults of " + channel + " must be a map of key: value"};
        }
        StreamFaults f;
        for (const auto& item : stream.second) {
          const std::string name = item.first.as<std::string>();
          const Key* key = nullptr;
          for (const Key& k : kKeys) {
            if (name == k.name) key = &k;
          }
          if (key == nullptr) {
            return Error{at(origin, item.first) + ": unknown key '" + name + "' in the faults of " + channel +
                         " (known: " + known_keys() + ")"};
          }
          double value;
          try {
            value = item.second.as<double>();
          } catch (const YAML::Exception&) {
            return Error{at(origin, item.second) + ": " + channel + "." + name + " must be a number"};
          }
          if (!std::isfinite(value) || value < key->min || value > key->max) {
            std::ostringstream range;
            range << key->min << ".." << key->max;
            return Error{at(origin, item.second) + ": " + channel + "." + name + " = " + item.second.as<std::string>() +
                         " is outside " + range.str()};
          }
          f.*(key->field) = value;
        }
        if ((f.burst_enter > 0) != (f.burst_exit > 0)) {
          return Error{at(origin, stream.second) + ": " + channel + " needs both burst_enter and burst_exit"};
        }
        config.streams[channel] = f;
      }
    } else {
      return Error{at(origin, top.first) + ": unknown key '" + key + "' (known: seed, streams)"};
    }
  }
  return config;
}

Result<FaultConfig> load_faults(const std::string& path) {
  std::ifstream f(path);
  if (!f) return Error{path + ": cannot open the fault description"};
  std::stringstream text;
  text << f.rdbuf();
  return parse_faults(text.str(), path);
}

StreamFaultInjector::StreamFaultInjector(std::string channel, StreamFaults faults, uint64_t seed, int64_t start_utime)
    : channel_(std::move(channel)),
      f_(faults),
      start_utime_(start_utime),
      // One generator per stream, seeded from the run's seed and the channel, so streams are independent and
      // adding a stream does not change the others.
      rng_(seed ^ std::hash<std::string>{}(channel_)) {}

int64_t StreamFaultInjector::source_clock(int64_t true_utime) const {
  const double elapsed = static_cast<double>(true_utime - start_utime_);
  return true_utime + static_cast<int64_t>(std::llround(f_.clock_offset_s * 1e6 + elapsed * f_.clock_drift_ppm * 1e-6));
}

void StreamFaultInjector::apply(int64_t seq, int64_t true_utime, std::vector<Delivery>& out) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Draw every random number every time, so one fault's setting does not shift another's sequence.
  const double u_burst = uniform(rng_), u_drop = uniform(rng_), u_dup = uniform(rng_), u_reorder = uniform(rng_);
  const double jitter = f_.jitter_s > 0 ? std::exponential_distribution<double>(1.0 / f_.jitter_s)(rng_) : 0.0;
  const double jitter2 = f_.jitter_s > 0 ? std::exponential_distribution<double>(1.0 / f_.jitter_s)(rng_) : 0.0;
  if (f_.burst_enter > 0) in_burst_ = in_burst_ ? u_burst >= f_.burst_exit : u_burst < f_.burst_enter;
  if (in_burst_) {
    burst_dropped_.push_back(seq);
    return;
  }
  if (u_drop < f_.drop_probability) {
    dropped_.push_back(seq);
    return;
  }
  const int64_t stamp = source_clock(true_utime);
  double delay = f_.latency_s + jitter;
  if (u_reorder < f_.reorder_probability) {
    delay += f_.reorder_delay_s;
    reordered_.push_back(seq);
  }
  out.push_back({stamp, true_utime + static_cast<int64_t>(std::llround(delay * 1e6))});
  if (u_dup < f_.duplicate_probability) {
    duplicated_.push_back(seq);
    out.push_back({stamp, true_utime + static_cast<int64_t>(std::llround((delay + jitter2) * 1e6)) + 1});
  }
}

std::vector<driftlab::fault_t> StreamFaultInjector::manifest(int64_t end_utime) const {
  std::vector<driftlab::fault_t> out;
  const int64_t s = start_utime_, e = end_utime;
  if (f_.clock_offset_s != 0) out.push_back(fault(channel_, "clock_offset", s, e, {{"offset_s", f_.clock_offset_s}}));
  if (f_.clock_drift_ppm != 0) out.push_back(fault(channel_, "clock_drift", s, e, {{"drift_ppm", f_.clock_drift_ppm}}));
  if (f_.latency_s != 0) out.push_back(fault(channel_, "latency", s, e, {{"latency_s", f_.latency_s}}));
  if (f_.jitter_s != 0) out.push_back(fault(channel_, "jitter", s, e, {{"mean_s", f_.jitter_s}}));
  if (f_.drop_probability != 0) {
    out.push_back(fault(channel_, "drop", s, e, {{"probability", f_.drop_probability}}, dropped_));
  }
  if (f_.burst_enter != 0) {
    out.push_back(fault(channel_, "burst_drop", s, e, {{"enter_probability", f_.burst_enter}, {"exit_probability", f_.burst_exit}},
                        burst_dropped_));
  }
  if (f_.duplicate_probability != 0) {
    out.push_back(fault(channel_, "duplicate", s, e, {{"probability", f_.duplicate_probability}}, duplicated_));
  }
  if (f_.reorder_probability != 0) {
    out.push_back(fault(channel_, "reorder", s, e,
                        {{"probability", f_.reorder_probability}, {"delay_s", f_.reorder_delay_s}}, reordered_));
  }
  return out;
}

}  // namespace driftlab
