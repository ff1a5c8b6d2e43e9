// Reading configuration maps from YAML with errors that name the file, the line and the key: every key must be
// read (what is left is an unknown key), every number is range-checked. Used by the simulator's scenarios and the
// replay modules' configs.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab {

/// "ORIGIN:LINE" of a node (1-based line).
inline std::string at(const std::string& origin, const YAML::Node& node) {
  return origin + ":" + std::to_string(node.Mark().line + 1);
}

/// Reads the keys of one YAML map into fields, and names the file, line and key when something is wrong.
/// Every key must be consumed: what is left at the end is an unknown key.
class Fields {
 public:
  Fields(const YAML::Node& node, std::string origin, std::string what)
      : node_(node), origin_(std::move(origin)), what_(std::move(what)) {}

  Status is_map() const {
    if (!node_.IsMap()) return Error{at(origin_, node_) + ": " + what_ + " must be a map of key: value"};
    return {};
  }
  bool has(const char* key) const { return node_[key].IsDefined(); }
  const YAML::Node node(const char* key) {
    used_.insert(key);
    return node_[key];
  }
  std::string where(const char* key) const {
    const YAML::Node n = node_[key];
    return at(origin_, n.IsDefined() ? n : node_) + ": " + prefix() + key;
  }

  Status number(const char* key, double& out, double min, double max) {
    if (!has(key)) return {};
    const YAML::Node n = node(key);
    double v;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      return Error{where(key) + " must be a number"};
    }
    if (!std::isfinite(v) || v < min || v > max) {
      std::ostringstream s;
      s << where(key) << " = " << n.as<std::string>() << " is outside " << min << ".." << max;
      return Error{s.str()};
    }
    out = v;
    return {};
  }
  Status positive(const char* key, double& out) {
    if (!has(key)) return {};
    double v = out;
    if (Status s = number(key, v, -INFINITY, INFINITY); !s) return s;
    if (!(v > 0)) return Error{where(key) + " = " + node_[key].as<std::string>() + " must be > 0"};
    out = v;
    return {};
  }
  Status integer(const char* key, int& out, int min, int max) {
    double v = out;
    if (Status s = number(key, v, min, max); !s) return s;
    if (v != std::floor(v)) return Error{where(key) + " must be a whole number"};
    out = static_cast<int>(v);
    return {};
  }
  Status text(const char* key, std::string& out) {
    if (!has(key)) return {};
    const YAML::Node n = node(key);
    if (!n.IsScalar()) return Error{where(key) + " must be a string"};
    out = n.as<std::string>();
    return {};
  }
  Status boolean(const char* key, bool& out) {
    if (!has(key)) return {};
    try {
      out = node(key).as<bool>();
    } catch (const YAML::Exception&) {
      return Error{where(key) + " must be true or false"};
    }
    return {};
  }
  Status vector(const char* key, std::vector<double>& out, std::size_t n) {
    if (!has(key)) return {};
    const YAML::Node v = node(key);
    if (!v.IsSequence() || v.size() != n) {
      return Error{where(key) + " must be a list of " + std::to_string(n) + " numbers"};
    }
    out.clear();
    for (const auto& e : v) {
      try {
        out.push_back(e.as<double>());
      } catch (const YAML::Exception&) {
        return Error{where(key) + " must be a list of " + std::to_string(n) + " numbers"};
      }
      if (!std::isfinite(out.back())) return Error{where(key) + " must hold finite numbers"};
    }
    return {};
  }
  /// Fails on the first key that no one read.
  Status finish(const std::string& known) const {
    for (const auto& kv : node_) {
      const std::string key = kv.first.as<std::string>();
      if (!used_.count(key)) {
        return Error{at(origin_, kv.first) + ": unknown key '" + prefix() + key + "' (known: " + known + ")"};
      }
    }
    return {};
  }

 private:
  std::string prefix() const { return what_.empty() ? std::string() : what_ + "."; }
  YAML::Node node_;
  std::string origin_, what_;
  std::set<std::string> used_;
};

#define DL_TRY(expr)                 \
  do {                               \
    if (Status s_ = (expr); !s_) {   \
      return Error{s_.message()};    \
    }                                \
  } while (0)

}  // namespace driftlab
