// The .msg grammar (wiki.ros.org/msg, design.ros2.org "Interface definition"): one field per line, `TYPE NAME`
// with an optional ROS 2 default value after the name; `TYPE NAME=VALUE` is a constant (not serialized); `#` starts
// a comment; TYPE is a primitive or a message type, with `[]` (sequence), `[N]` (fixed array) or `[<=N]` (bounded
// sequence) after it, and ROS 2 strings may be bounded (`string<=N`). A message type without data fields is
// serialized in CDR as one uint8 (ROS 2 adds `structure_needs_at_least_one_member` when it converts to IDL).
#include "formats/ros_definition.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <unordered_map>

#include "formats/internal/ros_reader.h"

namespace driftlab::formats {
namespace {

using internal::Reader;

struct Primitive {
  std::string_view name;
  uint8_t size;  // bytes (0 for strings)
};
constexpr Primitive kPrimitives[] = {
    {"bool", 1},    {"int8", 1},    {"uint8", 1},   {"int16", 2},  {"uint16", 2},  {"int32", 4},
    {"uint32", 4},  {"int64", 8},   {"uint64", 8},  {"float32", 4}, {"float64", 8}, {"string", 0},
    {"wstring", 0}, {"time", 8},    {"duration", 8},
};

const Primitive* primitive(std::string_view name) {
  for (const auto& p : kPrimitives)
    if (p.name == name) return &p;
  return nullptr;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::string without_msg(std::string_view name) {
  std::string s(name);
  if (auto p = s.find("/msg/"); p != std::string::npos) s.erase(p, 4);
  return s;
}

bool valid_identifier(std::string_view s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])))) return false;
  for (char c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  return true;
}

bool valid_type_name(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '/') return false;
  return true;
}

bool parse_u32(std::string_view s, uint32_t* out) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), *out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

struct PendingField {
  RosField field;
  std::string type_text;  // the complex type as written, resolved once all sections are known
  size_t line = 0;
};

/// Writes JSON text; a null Out* walks without writing (a check).
class Json {
 public:
  std::string s;
  void raw(std::string_view v) { s += v; }
  void key(std::string_view k, bool first) {
    if (!first) s += ',';
    str(k);
    s += ':';
  }
  void str(std::string_view v) {
    s += '"';
    for (const char c : v) {
      const auto u = static_cast<unsigned char>(c);
      if (c == '"' || c == '\\') {
        s += '\\';
        s += c;
      } else if (u < 0x20) {
        char buf[8];
        std::snprintf(buf, sizeof(buf), "\\u%04x", u);
        s += buf;
      } else {
        s += c;
      }
    }
    s += '"';
  }
  void number(double v) {
    if (!std::isfinite(v)) {
      s += "null";
      return;
    }
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.17g", v);
    s += buf;
  }
  template <typename T>
  void integer(T v) {
    s += std::to_string(v);
  }
};

constexpr size_t kMaxDepth = 64;  // how deep types may nest

class Walker {
 public:
  Walker(const RosDefinition& d, Reader& r, Json* out, size_t budget) : d_(d), r_(r), out_(out), budget_(budget) {}

  void type(int index, int depth) {
    const RosType& t = d_.types()[static_cast<size_t>(index)];
    if (depth > static_cast<int>(kMaxDepth)) {
      r_.fail("types nested more than " + std::to_string(kMaxDepth) + " deep");
      return;
    }
    if (out_) out_->raw("{");
    if (t.fields.empty()) {
      if (r_.cdr()) r_.get<uint8_t>();  // structure_needs_at_least_one_member
    }
    bool first = true;
    for (const auto& f : t.fields) {
      if (!r_.ok()) break;
      if (out_) out_->key(f.name, first);
      first = false;
      field(f, depth);
    }
    if (out_) out_->raw("}");
  }

 private:
  void field(const RosField& f, int depth) {
    if (f.array == RosField::Array::kNone) {
      one(f, depth);
      return;
    }
    uint32_t n = f.length;
    if (f.array == RosField::Array::kSequence) {
      n = r_.count(f.complex >= 0 ? 0 : std::max<size_t>(1, primitive(f.type)->size));
      if (!r_.ok()) return;
      if (f.length != 0 && n > f.length) {
        r_.fail(f.name + ": a sequence of " + std::to_string(n) + " elements, bounded to " + std::to_string(f.length));
        return;
      }
    }
    if (out_) out_->raw("[");
    for (uint32_t i = 0; i < n && r_.ok(); ++i) {
      if (out_ && i) out_->raw(",");
      one(f, depth);
    }
    if (out_) out_->raw("]");
  }

  void one(const RosField& f, int depth) {
    if (budget_-- == 0) {
      r_.fail("the definition asks for more elements than the message can hold");
      return;
    }
    if (f.complex >= 0) {
      type(f.complex, depth + 1);
      return;
    }
    const std::string& t = f.type;
    // Ordered by how often robots use them.
    if (t == "float64") return num(r_.get<double>());
    if (t == "float32") return num(static_cast<double>(r_.get<float>()));
    if (t == "string") {
      std::string s = r_.str();
      if (out_ && r_.ok()) out_->str(s);
      return;
    }
    if (t == "uint8") return integer(r_.get<uint8_t>());
    if (t == "int32") return integer(r_.get<int32_t>());
    if (t == "uint32") return integer(r_.get<uint32_t>());
    if (t == "int8") return integer(r_.get<int8_t>());
    if (t == "int16") return integer(r_.get<int16_t>());
    if (t == "uint16") return integer(r_.get<uint16_t>());
    if (t == "int64") return integer(r_.get<int64_t>());
    if (t == "uint64") return integer(r_.get<uint64_t>());
    if (t == "bool") {
      const uint8_t b = r_.get<uint8_t>();
      if (out_ && r_.ok()) out_->raw(b ? "true" : "false");
      return;
    }
    if (t == "time" || t == "duration") {
      // ROS 1: time is two uint32, duration two int32; CDR (Foxglove's reading): int32 sec, uint32 nanosec.
      const bool ros1 = !r_.cdr();
      int64_t sec, nsec;
      if (ros1 && t == "time") {
        sec = r_.get<uint32_t>();
        nsec = r_.get<uint32_t>();
      } else if (ros1) {
        sec = r_.get<int32_t>();
        nsec = r_.get<int32_t>();
      } else {
        sec = r_.get<int32_t>();
        nsec = r_.get<uint32_t>();
      }
      if (out_ && r_.ok()) {
        out_->raw("{\"sec\":" + std::to_string(sec) + (ros1 ? ",\"nsec\":" : ",\"nanosec\":") + std::to_string(nsec) +
                  "}");
      }
      return;
    }
    r_.fail(f.name + ": " + t + " is not supported");  // wstring: no ROS 2 message a robot records uses it
  }
  void num(double v) {
    if (out_ && r_.ok()) out_->number(v);
  }
  template <typename T>
  void integer(T v) {
    if (out_ && r_.ok()) out_->integer(v);
  }

  const RosDefinition& d_;
  Reader& r_;
  Json* out_;
  size_t budget_;
};

}  // namespace

Result<RosDefinition> RosDefinition::parse(std::string_view type_name, std::string_view text,
                                           Serialization serialization) {
  const bool ros1 = serialization == Serialization::kRos1;
  RosDefinition d;
  d.serialization_ = serialization;
  std::vector<std::vector<PendingField>> pending;
  d.types_.push_back({without_msg(type_name), {}});
  pending.emplace_back();
  size_t line_no = 0;
  bool expect_msg_line = false;
  size_t start = 0;
  while (start <= text.size()) {
    size_t nl = text.find('\n', start);
    if (nl == std::string_view::npos) nl = text.size();
    std::string_view line = text.substr(start, nl - start);
    start = nl + 1;
    ++line_no;
    std::string_view t = trim(line);
    if (t.size() >= 3 && t.find_first_not_of('=') == std::string_view::npos) {
      expect_msg_line = true;
      continue;
    }
    if (expect_msg_line) {
      if (t.empty()) continue;
      if (!t.starts_with("MSG:")) {
        return Error("line " + std::to_string(line_no) + ": \"" + std::string(t.substr(0, 40)) +
                     "\" where a \"MSG: pkg/Type\" line should follow the separator");
      }
      const std::string name = without_msg(trim(t.substr(4)));
      if (!valid_type_name(name)) return Error("line " + std::to_string(line_no) + ": a MSG line without a type name");
      d.types_.push_back({name, {}});
      pending.emplace_back();
      expect_msg_line = false;
      continue;
    }
    if (const size_t hash = t.find('#'); hash != std::string_view::npos) t = trim(t.substr(0, hash));
    if (t.empty()) continue;
    const size_t sp = t.find_first_of(" \t");
    if (sp == std::string_view::npos) {
      return Error("line " + std::to_string(line_no) + ": \"" + std::string(t.substr(0, 40)) + "\" has no field name");
    }
    std::string_view type_text = t.substr(0, sp);
    std::string_view rest = trim(t.substr(sp));
    const size_t name_end = std::min(rest.find_first_of(" \t="), rest.size());
    const std::string_view name = rest.substr(0, name_end);
    if (trim(rest.substr(name_end)).starts_with("=")) continue;  // a constant
    if (!valid_identifier(name)) {
      return Error("line " + std::to_string(line_no) + ": \"" + std::string(name.substr(0, 40)) +
                   "\" is not a field name");
    }
    PendingField p;
    p.line = line_no;
    p.field.name = std::string(name);
    if (const size_t br = type_text.find('['); br != std::string_view::npos) {
      if (!type_text.ends_with("]")) return Error("line " + std::to_string(line_no) + ": an array type without ']'");
      std::string_view inside = type_text.substr(br + 1, type_text.size() - br - 2);
      type_text = type_text.substr(0, br);
      if (inside.empty()) {
        p.field.array = RosField::Array::kSequence;
      } else if (inside.starts_with("<=")) {
        p.field.array = RosField::Array::kSequence;
        if (!parse_u32(inside.substr(2), &p.field.length)) {
          return Error("line " + std::to_string(line_no) + ": a sequence bound that is not a number");
        }
      } else {
        p.field.array = RosField::Array::kFixed;
        if (!parse_u32(inside, &p.field.length)) {
          return Error("line " + std::to_string(line_no) + ": an array length that is not a number");
        }
      }
    }
    if (const size_t bound = type_text.find("<="); bound != std::string_view::npos) {
      type_text = type_text.substr(0, bound);  // a bounded string: read like any string
    }
    std::string base(type_text);
    if (base == "byte") base = ros1 ? "int8" : "uint8";
    if (base == "char") base = "uint8";
    if (ros1 && base == "Header") base = "std_msgs/Header";
    if (primitive(base)) {
      p.field.type = base;
    } else if (valid_type_name(base)) {
      p.type_text = base;
    } else {
      return Error("line " + std::to_string(line_no) + ": \"" + base.substr(0, 40) + "\" is not a type");
    }
    pending.back().push_back(std::move(p));
  }

  // Message types named in fields: fully qualified, in the same package, or by a unique short name. Looked up in
  // hash maps: 90,000 types in packages of their own, each naming the next by its short name, were each looked
  // for among all the others (quadratic).
  std::unordered_map<std::string, int> by_name;
  for (size_t i = 0; i < d.types_.size(); ++i) by_name.emplace(d.types_[i].name, static_cast<int>(i));
  std::unordered_map<std::string, int> by_short;  // the name after the package; -2: more than one type has it
  for (const auto& [n, idx] : by_name) {
    const size_t slash = n.rfind('/');
    if (slash == std::string::npos) continue;
    auto [it, fresh] = by_short.emplace(n.substr(slash + 1), idx);
    if (!fresh) it->second = -2;
  }
  for (size_t i = 0; i < d.types_.size(); ++i) {
    const std::string& owner = d.types_[i].name;
    const std::string package = owner.substr(0, owner.find('/'));
    for (auto& p : pending[i]) {
      if (!p.type_text.empty()) {
        const std::string want = without_msg(p.type_text);
        int found = -1;
        if (auto it = by_name.find(want); it != by_name.end()) {
          found = it->second;
        } else if (want.find('/') == std::string::npos) {
          if (auto it2 = by_name.find(package + "/" + want); it2 != by_name.end()) {
            found = it2->second;
          } else if (auto it3 = by_short.find(want); it3 != by_short.end()) {
            if (it3->second == -2) return Error("line " + std::to_string(p.line) + ": type " + want + " is ambiguous");
            found = it3->second;
          }
        }
        if (found < 0) {
          return Error("line " + std::to_string(p.line) + ": type " + p.type_text + " is not defined in the schema");
        }
        p.field.complex = found;
        p.field.type = d.types_[static_cast<size_t>(found)].name;
      }
      d.types_[i].fields.push_back(std::move(p.field));
    }
  }
  // A type that contains itself can never end, and one nested deeper than a message is read through (kMaxDepth)
  // can never be read. Walked with a stack of its own, never recursively: a chain of 250,000 types overflowed the
  // call stack here.
  std::vector<uint8_t> state(d.types_.size(), 0);  // 0 new, 1 on the path, 2 done
  std::vector<size_t> below(d.types_.size(), 0);   // a done type: how deep types nest inside it
  std::vector<std::pair<int, size_t>> path;        // a type and its next field to look at
  path.emplace_back(0, 0);
  state[0] = 1;
  while (!path.empty()) {
    const int t = path.back().first;
    const auto& fields = d.types_[static_cast<size_t>(t)].fields;
    if (path.back().second == fields.size()) {
      state[static_cast<size_t>(t)] = 2;
      for (const auto& f : fields)
        if (f.complex >= 0)
          below[static_cast<size_t>(t)] =
              std::max(below[static_cast<size_t>(t)], below[static_cast<size_t>(f.complex)] + 1);
      path.pop_back();
      continue;
    }
    const int c = fields[path.back().second++].complex;
    if (c < 0) continue;
    if (state[static_cast<size_t>(c)] == 1) return Error("type " + d.types_[0].name + " contains itself");
    if (path.size() + (state[static_cast<size_t>(c)] == 2 ? below[static_cast<size_t>(c)] : 0) > kMaxDepth) {
      return Error("type " + d.types_[0].name + " nests types more than " + std::to_string(kMaxDepth) +
                   " deep (through " + d.types_[static_cast<size_t>(c)].name +
                   "), more than a message is read through");
    }
    if (state[static_cast<size_t>(c)] == 2) continue;
    state[static_cast<size_t>(c)] = 1;
    path.emplace_back(c, 0);
  }
  return d;
}

namespace {
std::string walk(const RosDefinition& d, std::span<const uint8_t> payload, Json* out) {
  Reader r(payload, d.serialization());
  // Every element read consumes at least a byte, except empty ROS 1 messages; this bounds the work either way.
  Walker w(d, r, out, payload.size() * 8 + 4096);
  if (r.ok()) w.type(0, 0);
  // Bytes after the message are allowed, as CDR readers allow them (a newer publisher may have added fields);
  // a message that ends before its schema does is not one.
  return r.ok() ? std::string() : r.error();
}
}  // namespace

std::string RosDefinition::check(std::span<const uint8_t> payload) const { return walk(*this, payload, nullptr); }

Result<std::string> RosDefinition::to_json(std::span<const uint8_t> payload) const {
  Json out;
  std::string error = walk(*this, payload, &out);
  if (!error.empty()) return Error(error);
  return std::move(out.s);
}

}  // namespace driftlab::formats
