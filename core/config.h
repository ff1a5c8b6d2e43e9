// One declarative config layer: a struct's options are declared once, as a table of key, member, unit, range and a
// one-line description, and everything else comes from the table: reading a YAML map into the struct (every number
// checked for type, finiteness and range; every error one line, "FILE:LINE: dotted.key = value is outside 0..1"),
// the unknown-key error listing the known keys, and the reference (a markdown table of key, type, unit, default,
// range and description, the defaults taken from a default-constructed struct).
//
//   const config::Table<EstimatorConfig>& table() {
//     static const auto t = config::Table<EstimatorConfig>()
//         .number("window_s", &EstimatorConfig::window_s, config::between(0, 60), "s", "how far back ...")
//         .number("publish_rate", &EstimatorConfig::publish_rate, config::between(0.1, 1000), "Hz", "output rate");
//     return t;
//   }
//   Result<EstimatorConfig> c = table().parse(config::Value(node, "modules.yaml", "estimator"));
//
// Thread-safety: build a table once (a function-local static), then only read it; reading is reentrant.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/result.h"

namespace driftlab::config {

/// The values a number may take; any value must also be finite. Infinite bounds mean "no bound".
struct Range {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false;  ///< min itself is excluded
  bool max_open = false;  ///< max itself is excluded

  bool contains(double v) const;
  /// "0.1..1000", "> 0", ">= 1", "> 0 and <= 0.02", "any".
  std::string text() const;
  /// What is wrong with v for a message: "is outside 0.1..1000 Hz", "must be > 0", "must be <= 1000 Hz"; empty when
  /// v is in range.
  std::string violation(double v, const std::string& unit) const;
};
/// min <= v <= max
constexpr Range between(double min, double max) { return {min, max, false, false}; }
/// min < v <= max
constexpr Range above(double min, double max = std::numeric_limits<double>::infinity()) {
  return {min, max, true, false};
}
/// v >= min
constexpr Range at_least(double min) { return {min, std::numeric_limits<double>::infinity(), false, false}; }

/// The shortest text that reads back as exactly v: "1e+07", "0.015", "-1", "1763776800".
std::string format_number(double v);
/// The text of a bad value as a message quotes it: never more than 24 characters (a 309-digit number is cut).
std::string quoted(const std::string& text);

/// A YAML value being read, with the file it came from and its dotted key ("slam.2d.voxel", "route[2]"), so that
/// every message is "FILE:LINE: KEY ...". The document itself has an empty key.
class Value {
 public:
  Value(YAML::Node node, std::string file, std::string key = "");

  const YAML::Node& node() const { return node_; }
  const std::string& file() const { return file_; }
  const std::string& key() const { return key_; }
  /// Given, and not YAML's null ("key:" with nothing after it).
  bool given() const { return node_.IsDefined() && !node_.IsNull(); }
  /// "FILE:LINE" of the value; of its key when it is null, of the map it is missing from when it is missing.
  std::string place() const;
  /// "FILE:LINE: KEY WHAT" ("FILE:LINE: WHAT" for the document itself).
  Error error(const std::string& what) const;
  /// The entry `name` of this map (key "KEY.name"); when it is missing, its place is this map's.
  Value operator[](const std::string& name) const;
  /// Element i of this list (key "KEY[i]").
  Value operator[](std::size_t i) const;
  /// Calls fn(name, value, key) for each entry of this map, in order, after checking that it is a map whose keys are
  /// names, none given twice; `key` is the key itself (its line, for messages about the key).
  Status entries(const std::function<Status(const std::string& name, const Value& value, const Value& key)>& fn) const;

  // Scalars. Each refuses, in one line, a missing value, a list or map, text that is not of the type, NaN and
  // infinities, numbers too large for a double or for the integer type, and values out of range; the offending text
  // is quoted up to 24 characters. Integers accept "1e3" and "5.0" (whole numbers written as decimals).
  Result<double> number(const Range& range = {}, const std::string& unit = "") const;
  Result<int64_t> integer(const Range& range = {}, const std::string& unit = "") const;
  Result<uint64_t> unsigned_integer(const Range& range = {}, const std::string& unit = "") const;
  Result<bool> boolean() const;  ///< YAML's true/false, yes/no, on/off
  Result<std::string> text() const;
  /// One of `choices`: "KEY = lidar must be auto, 2d or 3d".
  Result<std::string> choice(const std::vector<std::string>& choices) const;
  /// A list of exactly n numbers, each in range.
  Result<std::vector<double>> numbers(std::size_t n, const Range& range = {}, const std::string& unit = "") const;

 private:
  Value(YAML::Node node, std::string file, std::string key, YAML::Mark fallback);
  YAML::Node node_;
  std::string file_, key_;
  YAML::Mark fallback_;  ///< where a missing value is reported: the map it is missing from
};

/// "a, b or c"
std::string one_of(const std::vector<std::string>& names);

/// Parses YAML text; a syntax error is one line, "FILE:LINE: what yaml-cpp says".
Result<YAML::Node> parse_yaml(const std::string& text, const std::string& file);
/// Reads and parses a YAML file; "PATH: cannot open the WHAT" when it cannot be read.
Result<YAML::Node> load_yaml(const std::string& path, const std::string& what);

namespace detail {

struct Schema;

/// One key of a table, type-erased: `void*` is the struct the table describes.
struct Field {
  std::string key, type, unit, range, doc;
  std::string default_text;  ///< shown instead of the struct's default when set
  bool required = false;
  bool brief = false;  ///< a section shown as one row in the reference, not key by key
  std::function<Status(const Value&, void*)> read;
  std::function<std::string(const void*)> show;  ///< the value as the reference prints it
  std::shared_ptr<const Schema> section;         ///< the keys of a sub-map (a section, or each entry of a map)
  std::function<const void*(const void*)> section_of;  ///< a section's struct within ours; empty for a map
  std::string entry;                              ///< a map: what an entry's key names ("CHANNEL")
};

struct Schema {
  std::string doc;
  std::vector<Field> fields;
  std::vector<std::function<Status(const Value&, void*)>> checks;
  std::function<std::shared_ptr<const void>()> defaults;
  Status read(const Value& v, void* obj) const;
  std::string known() const;
  void rows(std::string& out, const std::string& prefix, const void* defaults) const;
};

template <class V>
constexpr std::size_t fixed_size() {
  if constexpr (requires { std::tuple_size<V>::value; }) {
    return std::tuple_size<V>::value;
  } else {
    return static_cast<std::size_t>(V::SizeAtCompileTime);  // Eigen's fixed-size vectors
  }
}

std::string show_numbers(const double* v, std::size_t n);
std::string show_text(const std::string& s);

}  // namespace detail

/// Strings: whether "" is allowed.
enum class Text { kAny, kNonEmpty };

/// The options of a struct T, key by key. The adders return *this, so a table is declared as one expression; the
/// modifiers (required, shown_default, brief) apply to the key added last.
template <class T>
class Table {
 public:
  Table() : s_(std::make_shared<detail::Schema>()) {
    s_->defaults = [] { return std::static_pointer_cast<const void>(std::make_shared<const T>()); };
  }

  Table& number(const char* key, double T::*m, Range r, const char* unit, const char* doc) {
    return add(key, "number", unit, r.text(), doc,
               [m, r, u = std::string(unit)](const Value& v, T& t) { return set(v.number(r, u), t.*m); },
               [m](const T& t) { return format_number(t.*m); });
  }
  /// int, int64_t or uint64_t.
  template <class I>
  Table& integer(const char* key, I T::*m, Range r, const char* unit, const char* doc) {
    static_assert(std::is_integral_v<I> && !std::is_same_v<I, bool>);
    return add(key, "integer", unit, r.text(), doc,
               [m, r, u = std::string(unit)](const Value& v, T& t) -> Status {
                 if constexpr (std::is_unsigned_v<I>) {
                   static_assert(sizeof(I) == 8, "unsigned: uint64_t only");
                   return set(v.unsigned_integer(r, u), t.*m);
                 } else {
                   auto x = v.integer(r, u);
                   if (!x) return x.error();
                   if (*x < std::numeric_limits<I>::min() || *x > std::numeric_limits<I>::max()) {
                     return v.error("= " + std::to_string(*x) + " is too large for this setting");
                   }
                   t.*m = static_cast<I>(*x);
                   return {};
                 }
               },
               [m](const T& t) { return std::to_string(t.*m); });
  }
  Table& flag(const char* key, bool T::*m, const char* doc) {
    return add(key, "bool", "", "", doc, [m](const Value& v, T& t) { return set(v.boolean(), t.*m); },
               [m](const T& t) { return std::string(t.*m ? "true" : "false"); });
  }
  Table& text(const char* key, std::string T::*m, const char* doc, Text kind = Text::kAny) {
    return add(key, "string", "", kind == Text::kNonEmpty ? "not empty" : "", doc,
               [m, kind](const Value& v, T& t) -> Status {
                 auto x = v.text();
                 if (!x) return x.error();
                 if (kind == Text::kNonEmpty && x->empty()) return v.error("must not be empty");
                 t.*m = std::move(*x);
                 return {};
               },
               [m](const T& t) { return detail::show_text(t.*m); });
  }
  /// A string that must be one of `choices`.
  Table& choice(const char* key, std::string T::*m, std::vector<std::string> choices, const char* doc) {
    const std::string range = one_of(choices);
    return add(key, "choice", "", range, doc,
               [m, choices = std::move(choices)](const Value& v, T& t) { return set(v.choice(choices), t.*m); },
               [m](const T& t) { return t.*m; });
  }
  /// An enum member, by name.
  template <class E>
  Table& choice(const char* key, E T::*m, std::vector<std::pair<std::string, E>> choices, const char* doc) {
    std::vector<std::string> names;
    for (const auto& c : choices) names.push_back(c.first);
    return add(key, "choice", "", one_of(names), doc,
               [m, choices, names](const Value& v, T& t) -> Status {
                 auto x = v.choice(names);
                 if (!x) return x.error();
                 for (const auto& c : choices) {
                   if (c.first == *x) t.*m = c.second;
                 }
                 return {};
               },
               [m, choices](const T& t) {
                 for (const auto& c : choices) {
                   if (c.second == t.*m) return c.first;
                 }
                 return std::string();
               });
  }
  /// A fixed-size vector of numbers (std::array<double, N>, Eigen::Vector3d), written [a, b, c].
  template <class V>
  Table& numbers(const char* key, V T::*m, Range r, const char* unit, const char* doc) {
    using Array = std::array<double, detail::fixed_size<V>()>;
    return add(key, "[" + std::to_string(Array().size()) + " numbers]", unit, r.text(), doc,
               [m, r, u = std::string(unit)](const Value& v, T& t) -> Status {
                 auto x = v.numbers(Array().size(), r, u);
                 if (!x) return x.error();
                 for (std::size_t i = 0; i < x->size(); ++i) (t.*m)[i] = (*x)[i];
                 return {};
               },
               [m](const T& t) {
                 Array a;
                 for (std::size_t i = 0; i < a.size(); ++i) a[i] = (t.*m)[i];
                 return detail::show_numbers(a.data(), a.size());
               });
  }
  /// A struct of numbers written as a list: numbers("start", &C::start, {&Pose2::x, &Pose2::y, &Pose2::yaw}, ...).
  template <class P>
  Table& numbers(const char* key, P T::*m, std::initializer_list<double P::*> parts, Range r, const char* unit,
                 const char* doc) {
    std::vector<double P::*> p(parts);
    return add(key, "[" + std::to_string(p.size()) + " numbers]", unit, r.text(), doc,
               [m, p, r, u = std::string(unit)](const Value& v, T& t) -> Status {
                 auto x = v.numbers(p.size(), r, u);
                 if (!x) return x.error();
                 for (std::size_t i = 0; i < p.size(); ++i) (t.*m).*p[i] = (*x)[i];
                 return {};
               },
               [m, p](const T& t) {
                 std::vector<double> a;
                 for (auto part : p) a.push_back((t.*m).*part);
                 return detail::show_numbers(a.data(), a.size());
               });
  }
  /// A sub-map read into member m with its own table: keys "KEY.sub" (section(key, table) for keys of T itself).
  template <class S>
  Table& section(const char* key, S T::*m, const Table<S>& sub, const char* doc) {
    detail::Field f = field(key, "map", "", "", doc);
    f.read = [m, s = sub.schema()](const Value& v, void* o) { return s->read(v, &(static_cast<T*>(o)->*m)); };
    f.section = sub.schema();
    f.section_of = [m](const void* o) -> const void* { return &(static_cast<const T*>(o)->*m); };
    return push(std::move(f));
  }
  Table& section(const char* key, const Table<T>& sub, const char* doc) {
    detail::Field f = field(key, "map", "", "", doc);
    f.read = [s = sub.schema()](const Value& v, void* o) { return s->read(v, o); };
    f.section = sub.schema();
    f.section_of = [](const void* o) { return o; };
    return push(std::move(f));
  }
  /// A map of name -> sub-map, each read with `sub` ("streams: {IMU: {...}, SCAN: {...}}"); `entry` names what the
  /// names are, for the reference ("CHANNEL": keys "KEY.<CHANNEL>.sub"). The map given replaces the default.
  template <class S>
  Table& map(const char* key, std::map<std::string, S> T::*m, const char* entry, const Table<S>& sub, const char* doc) {
    detail::Field f = field(key, "map", "", "", doc);
    f.read = [m, s = sub.schema(), entry = std::string(entry)](const Value& v, void* o) -> Status {
      std::map<std::string, S> out;
      if (v.given()) {
        if (!v.node().IsMap()) return v.error("must be a map of " + entry + ": {" + s->known() + "}");
        Status st = v.entries([&](const std::string& name, const Value& value, const Value&) -> Status {
          S entry;
          if (Status e = s->read(value, &entry); !e) return e;
          out[name] = std::move(entry);
          return {};
        });
        if (!st) return st;
      }
      static_cast<T*>(o)->*m = std::move(out);
      return {};
    };
    f.section = sub.schema();
    f.entry = entry;
    return push(std::move(f));
  }
  /// The keys of sub, read into member m, at this level (flat: "lookahead", not "pursuit.lookahead").
  template <class S>
  Table& include(S T::*m, const Table<S>& sub) {
    for (detail::Field f : sub.schema()->fields) {
      auto at = [m](const void* o) -> const void* { return &(static_cast<const T*>(o)->*m); };
      f.read = [r = f.read, m](const Value& v, void* o) { return r(v, &(static_cast<T*>(o)->*m)); };
      if (f.show) f.show = [s = f.show, at](const void* o) { return s(at(o)); };
      if (f.section_of) f.section_of = [s = f.section_of, at](const void* o) { return s(at(o)); };
      push(std::move(f));
    }
    for (const auto& c : sub.schema()->checks) {
      s_->checks.push_back([c, m](const Value& v, void* o) { return c(v, &(static_cast<T*>(o)->*m)); });
    }
    return *this;
  }
  /// A value of any other type M, read by `read` (which reports through the Value it is given).
  template <class M>
  Table& custom(const char* key, M T::*m, const char* type, const char* unit, const char* range, const char* doc,
                std::function<Status(const Value&, M&)> read, std::function<std::string(const M&)> show) {
    return add(key, type, unit, range, doc, [m, read](const Value& v, T& t) { return read(v, t.*m); },
               [m, show](const T& t) { return show(t.*m); });
  }

  /// The key added last must be given.
  Table& required() { return s_->fields.back().required = true, *this; }
  /// The key added last shows this as its default in the reference (e.g. "from `scenario`").
  Table& shown_default(const char* text) { return s_->fields.back().default_text = text, *this; }
  /// The section added last shows as one row in the reference (its keys are documented elsewhere).
  Table& brief() { return s_->fields.back().brief = true, *this; }
  /// A rule across keys, or a value derived from them, run after every key of a map was read; `map` is the map
  /// (map["key"].error("must exceed range_min") names a key).
  Table& check(std::function<Status(const Value& map, T&)> rule) {
    s_->checks.push_back([rule](const Value& v, void* o) { return rule(v, *static_cast<T*>(o)); });
    return *this;
  }
  /// What the table describes, in a sentence, for the reference.
  Table& describe(const char* text) { return s_->doc = text, *this; }

  /// Reads a YAML map into `out`: the keys given replace out's values; an absent or null node changes nothing
  /// (but required keys are still missing). Stops at the first error.
  Status read(const Value& v, T& out) const { return s_->read(v, &out); }
  /// The struct from `base` (default: a default-constructed T) and the keys given.
  Result<T> parse(const Value& v, T base = T{}) const {
    if (Status st = read(v, base); !st) return st.error();
    return base;
  }
  /// "a, b, c": the keys, in declaration order.
  std::string known_keys() const { return s_->known(); }
  /// The reference: a markdown table of key, type, unit, default, range and description, sub-maps as dotted keys
  /// under `prefix` ("faults." gives "faults.seed").
  std::string reference(const std::string& prefix = "") const {
    std::string out;
    if (!s_->doc.empty()) out += s_->doc + "\n\n";
    out += "| key | type | unit | default | range | description |\n|---|---|---|---|---|---|\n";
    const auto defaults = s_->defaults();
    s_->rows(out, prefix, defaults.get());
    return out;
  }
  const std::shared_ptr<detail::Schema>& schema() const { return s_; }

 private:
  template <class X>
  static Status set(Result<X> x, X& out) {
    if (!x) return x.error();
    out = std::move(*x);
    return {};
  }
  static detail::Field field(const char* key, std::string type, const char* unit, std::string range, const char* doc) {
    detail::Field f;
    f.key = key;
    f.type = std::move(type);
    f.unit = unit;
    f.range = std::move(range);
    f.doc = doc;
    return f;
  }
  Table& add(const char* key, std::string type, const char* unit, std::string range, const char* doc,
             std::function<Status(const Value&, T&)> read, std::function<std::string(const T&)> show) {
    detail::Field f = field(key, std::move(type), unit, std::move(range), doc);
    f.read = [read](const Value& v, void* o) { return read(v, *static_cast<T*>(o)); };
    f.show = [show](const void* o) { return show(*static_cast<const T*>(o)); };
    return push(std::move(f));
  }
  Table& push(detail::Field f) {
    s_->fields.push_back(std::move(f));
    return *this;
  }
  std::shared_ptr<detail::Schema> s_;
};

}  // namespace driftlab::config
