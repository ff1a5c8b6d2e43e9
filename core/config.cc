#include "core/config.h"

#include "core/closest_name.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <type_traits>

#include "core/text_file.h"

namespace driftlab::config {
namespace {

const char* shape(const YAML::Node& n) {
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  return "nothing";
}

enum class Parsed { kOk, kNotANumber, kNonFinite, kTooLarge };

/// A number as YAML writes it (1.5, -2, 1e7, .inf, .nan), parsed exactly and without the locale (std::from_chars).
/// yaml-cpp's own conversion is not used: it reports an overflowing "1e309" as "not a number" and lets "nan" through.
Parsed parse_number(std::string t, double& out) {
  if (!t.empty() && t[0] == '+') t.erase(0, 1);
  std::string lower;
  for (char c : t) lower += static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  if (lower == ".inf" || lower == "-.inf" || lower == ".nan") return Parsed::kNonFinite;
  if (t.empty()) return Parsed::kNotANumber;
  const char* end = t.data() + t.size();
  const auto [p, ec] = std::from_chars(t.data(), end, out);
  if (p != end) return Parsed::kNotANumber;
  if (ec == std::errc::result_out_of_range) {
    // Overflow, or underflow (1e-400), which is as good as 0: strtod tells them apart.
    const double d = std::strtod(t.c_str(), nullptr);
    if (std::isinf(d)) return Parsed::kTooLarge;
    out = d;
    return Parsed::kOk;
  }
  if (ec != std::errc()) return Parsed::kNotANumber;
  return std::isfinite(out) ? Parsed::kOk : Parsed::kNonFinite;
}

std::string with_unit(const std::string& unit) { return unit.empty() ? "" : " " + unit; }

}  // namespace

bool Range::contains(double v) const {
  if (!std::isfinite(v)) return false;
  if (min_open ? !(v > min) : !(v >= min)) return false;
  if (max_open ? !(v < max) : !(v <= max)) return false;
  return true;
}

std::string Range::text() const {
  const bool lo = std::isfinite(min), hi = std::isfinite(max);
  if (lo && hi && !min_open && !max_open) return format_number(min) + ".." + format_number(max);
  std::string out;
  if (lo) out += (min_open ? "> " : ">= ") + format_number(min);
  if (hi) out += (lo ? " and " : "") + std::string(max_open ? "< " : "<= ") + format_number(max);
  return out.empty() ? "any" : out;
}

std::string Range::violation(double v, const std::string& unit) const {
  if (contains(v)) return "";
  const bool lo = std::isfinite(min), hi = std::isfinite(max);
  if (lo && hi && !min_open && !max_open) return "is outside " + text() + with_unit(unit);
  // One bound: say the one that is broken (a bound of 0 needs no unit).
  if (lo && (min_open ? !(v > min) : !(v >= min))) {
    return std::string("must be ") + (min_open ? "> " : ">= ") + format_number(min) + (min != 0 ? with_unit(unit) : "");
  }
  return std::string("must be ") + (max_open ? "< " : "<= ") + format_number(max) + (max != 0 ? with_unit(unit) : "");
}

std::string quoted(const std::string& text) {
  if (text.size() <= 24) return text;
  return text.substr(0, 16) + "... (" + std::to_string(text.size()) + " characters)";
}

std::string format_number(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string one_of(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? " or " : ", ";
    out += names[i];
  }
  return out;
}

Result<YAML::Node> parse_yaml(const std::string& text, const std::string& file) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return Error{file + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
}

Result<YAML::Node> load_yaml(const std::string& path, const std::string& what) {
  auto text = read_text_file(path, what);
  if (!text) return text.error();
  return parse_yaml(*text, path);
}

Value::Value(YAML::Node node, std::string file, std::string key)
    : Value(std::move(node), std::move(file), std::move(key), YAML::Mark::null_mark()) {}

Value::Value(YAML::Node node, std::string file, std::string key, YAML::Mark fallback)
    : node_(std::move(node)), file_(std::move(file)), key_(std::move(key)), fallback_(fallback) {}

std::string Value::place() const {
  // A null value ("key:" and nothing) is reported on its key's line: yaml-cpp marks it at the next token.
  const bool marked = node_.IsDefined() && !node_.IsNull() && !node_.Mark().is_null();
  const YAML::Mark mark = marked ? node_.Mark() : fallback_;
  return mark.is_null() ? file_ : file_ + ":" + std::to_string(mark.line + 1);
}

Error Value::error(const std::string& what) const {
  return Error{place() + ": " + (key_.empty() ? what : key_ + " " + what)};
}

Value Value::operator[](const std::string& name) const {
  const std::string key = key_.empty() ? name : key_ + "." + name;
  if (node_.IsMap()) {
    for (const auto& kv : node_) {
      if (kv.first.IsScalar() && kv.first.Scalar() == name) return Value(kv.second, file_, key, kv.first.Mark());
    }
  }
  // Missing: reported where this map is.
  const bool marked = node_.IsDefined() && !node_.Mark().is_null();
  return Value(YAML::Node(YAML::NodeType::Undefined), file_, key, marked ? node_.Mark() : fallback_);
}

Value Value::operator[](std::size_t i) const {
  const YAML::Node& n = node_;
  const YAML::Mark here = node_.IsDefined() && !node_.Mark().is_null() ? node_.Mark() : fallback_;
  return Value(n.IsSequence() && i < n.size() ? n[i] : YAML::Node(YAML::NodeType::Undefined), file_,
               key_ + "[" + std::to_string(i) + "]", here);
}

Status Value::entries(const std::function<Status(const std::string&, const Value&, const Value&)>& fn) const {
  if (!node_.IsMap()) return error("must be a map of key: value");
  std::map<std::string, int> lines;
  for (const auto& kv : node_) {
    const Value key(kv.first, file_, key_, node_.Mark());
    if (!kv.first.IsScalar()) {
      return Error{key.place() + ": " + (key_.empty() ? "" : key_ + ": ") + "a key must be a name, not " +
                   shape(kv.first)};
    }
    const std::string& name = kv.first.Scalar();
    const Value value(kv.second, file_, key_.empty() ? name : key_ + "." + name, kv.first.Mark());
    if (auto [it, fresh] = lines.emplace(name, kv.first.Mark().line + 1); !fresh) {
      return Error{key.place() + ": " + value.key() + " is given twice (also on line " + std::to_string(it->second) +
                   ")"};
    }
    if (Status s = fn(name, value, key); !s) return s;
  }
  return {};
}

Result<double> Value::number(const Range& range, const std::string& unit) const {
  if (!given()) return error("has no value (a number is expected)");
  if (!node_.IsScalar()) return error(std::string("must be a number, not ") + shape(node_));
  const std::string& text = node_.Scalar();
  double v = 0;
  switch (parse_number(text, v)) {
    case Parsed::kOk:
      break;
    case Parsed::kNotANumber:
      return error("= " + quoted(text) + " must be a number");
    case Parsed::kNonFinite:
      return error("= " + quoted(text) + " must be a finite number");
    case Parsed::kTooLarge:
      return error("= " + quoted(text) + " is too large for a number");
  }
  if (const std::string why = range.violation(v, unit); !why.empty()) return error("= " + format_number(v) + " " + why);
  return v;
}

namespace {

/// A whole number of type I: exact when written as digits, else (1e3, 5.0) through a double that must be whole.
template <class I>
Result<I> whole_number(const Value& v, const Range& range, const std::string& unit) {
  const YAML::Node& node = v.node();
  if (!v.given()) return v.error("has no value (a whole number is expected)");
  if (!node.IsScalar()) return v.error(std::string("must be a whole number, not ") + shape(node));
  const std::string& raw = node.Scalar();
  const std::string text = !raw.empty() && raw[0] == '+' ? raw.substr(1) : raw;
  I x = 0;
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, x);
  if (p == end && ec == std::errc::result_out_of_range) return v.error("= " + quoted(raw) + " is too large for an integer");
  if (p != end || ec != std::errc() || text.empty()) {
    double d = 0;
    switch (parse_number(text, d)) {
      case Parsed::kOk:
        break;
      case Parsed::kNotANumber:
        return v.error("= " + quoted(raw) + " must be a whole number");
      case Parsed::kNonFinite:
        return v.error("= " + quoted(raw) + " must be a finite number");
      case Parsed::kTooLarge:
        return v.error("= " + quoted(raw) + " is too large for an integer");
    }
    if (d != std::floor(d)) return v.error("= " + format_number(d) + " must be a whole number");
    if (std::is_unsigned_v<I> && d < 0) return v.error("= " + format_number(d) + " must be >= 0");
    const double limit = std::ldexp(1.0, std::numeric_limits<I>::digits);  // 2^63, 2^64
    if (!(d < limit && d >= -limit)) return v.error("= " + format_number(d) + " is too large for an integer");
    x = static_cast<I>(d);
  }
  if (const std::string why = range.violation(static_cast<double>(x), unit); !why.empty()) {
    return v.error("= " + std::to_string(x) + " " + why);
  }
  return x;
}

}  // namespace

Result<int64_t> Value::integer(const Range& range, const std::string& unit) const {
  return whole_number<int64_t>(*this, range, unit);
}

Result<uint64_t> Value::unsigned_integer(const Range& range, const std::string& unit) const {
  return whole_number<uint64_t>(*this, range, unit);
}

Result<bool> Value::boolean() const {
  if (!given()) return error("has no value (true or false is expected)");
  if (!node_.IsScalar()) return error(std::string("must be true or false, not ") + shape(node_));
  try {
    return node_.as<bool>();  // YAML's spellings: true/false, yes/no, on/off, y/n, in three cases
  } catch (const YAML::Exception&) {
    return error("= " + quoted(node_.Scalar()) + " must be true or false");
  }
}

Result<std::string> Value::text() const {
  if (!given()) return error("has no value (write \"\" for an empty string)");
  if (!node_.IsScalar()) return error(std::string("must be a string, not ") + shape(node_));
  return node_.Scalar();
}

Result<std::string> Value::choice(const std::vector<std::string>& choices) const {
  if (!given()) return error("has no value (one of " + one_of(choices) + " is expected)");
  if (!node_.IsScalar()) return error("must be " + one_of(choices) + ", not " + shape(node_));
  const std::string& text = node_.Scalar();
  for (const auto& c : choices) {
    if (c == text) return text;
  }
  return error("= " + quoted(text) + " must be " + one_of(choices));
}

Result<std::vector<double>> Value::numbers(std::size_t n, const Range& range, const std::string& unit) const {
  if (!node_.IsSequence() || node_.size() != n) {
    return error("must be a list of " + std::to_string(n) + " numbers");
  }
  // "m, m, rad": one unit per element.
  std::vector<std::string> units;
  for (std::size_t from = 0, comma; from <= unit.size(); from = comma + 2) {
    comma = std::min(unit.find(", ", from), unit.size());
    units.push_back(unit.substr(from, comma - from));
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < n; ++i) {
    auto x = (*this)[i].number(range, units.size() == n ? units[i] : unit);
    if (!x) return x.error();
    out.push_back(*x);
  }
  return out;
}

namespace detail {

std::string show_numbers(const double* v, std::size_t n) {
  std::string out = "[";
  for (std::size_t i = 0; i < n; ++i) out += (i > 0 ? ", " : "") + format_number(v[i]);
  return out + "]";
}

std::string show_text(const std::string& s) { return s.empty() ? "\"\"" : s; }

Status Schema::read(const Value& v, void* obj) const {
  try {
    std::vector<bool> seen(fields.size(), false);
    if (v.given()) {
      if (!v.node().IsMap()) {
        if (v.key().empty()) return v.error("expected a map of key: value (" + known() + ")");
        return v.error("must be a map of key: value");
      }
      Status s = v.entries([&](const std::string& name, const Value& value, const Value& key) -> Status {
        for (std::size_t i = 0; i < fields.size(); ++i) {
          if (fields[i].key != name) continue;
          seen[i] = true;
          return fields[i].read(value, obj);
        }
        std::vector<std::string> keys;
        for (const auto& f : fields) keys.push_back(f.key);
        const std::string guess = closest_name(name, keys);
        return Error{key.place() + ": unknown key '" + value.key() + "'" +
                     (guess.empty() ? "" : ": did you mean '" + guess + "'?") + " (known: " + known() + ")"};
      });
      if (!s) return s;
    }
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].required && !seen[i]) {
        const std::string key = v.key().empty() ? fields[i].key : v.key() + "." + fields[i].key;
        return Error{v.place() + ": missing key '" + key + "' (" + fields[i].doc + ")"};
      }
    }
    if (!v.given()) return {};
    for (const auto& check : checks) {
      if (Status s = check(v, obj); !s) return s;
    }
    return {};
  } catch (const YAML::Exception& e) {
    // A shape no check above anticipated: still one line naming the place.
    return Error{v.file() + ":" + std::to_string(e.mark.line + 1) + ": " + (v.key().empty() ? "" : v.key() + ": ") +
                 e.msg};
  }
}

std::string Schema::known() const {
  std::string out;
  for (const Field& f : fields) out += (out.empty() ? "" : ", ") + f.key;
  return out;
}

void Schema::rows(std::string& out, const std::string& prefix, const void* defaults) const {
  auto cell = [](std::string s) {
    for (std::size_t i = 0; (i = s.find('|', i)) != std::string::npos; i += 2) s.insert(i, "\\");
    return s;
  };
  for (const Field& f : fields) {
    const std::string key = prefix + f.key;
    std::string shown = f.default_text;
    if (shown.empty() && f.required) shown = "required";
    if (shown.empty() && f.show) shown = "`" + f.show(defaults) + "`";
    const std::string type = f.section && !f.entry.empty() ? "map of " + f.entry + ": map" : f.type;
    out += "| `" + key + "` | " + cell(type) + " | " + cell(f.unit) + " | " + cell(shown) + " | " + cell(f.range) +
           " | " + cell(f.doc) + " |\n";
    if (!f.section || f.brief) continue;
    if (f.section_of) {
      f.section->rows(out, key + ".", f.section_of(defaults));
    } else {
      const auto entry_defaults = f.section->defaults();
      f.section->rows(out, key + ".<" + f.entry + ">.", entry_defaults.get());
    }
  }
}

}  // namespace detail
}  // namespace driftlab::config
