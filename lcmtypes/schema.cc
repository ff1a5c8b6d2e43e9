#include "lcmtypes/schema.h"

#include <cctype>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include "core/check.h"

namespace driftlab::lcmtypes {

extern const char kLcmDefinitions[];  // lcmtypes/*.lcm, concatenated (generated: lcm_definitions.cc)

namespace {

/// Tokens of LCM's grammar: identifiers (with dots), numbers and single punctuation; comments dropped.
std::vector<std::string> tokenize(std::string_view s) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < s.size()) {
    const char c = s[i];
    if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (s.compare(i, 2, "//") == 0) {
      i = s.find('\n', i);
      if (i == std::string_view::npos) break;
    } else if (s.compare(i, 2, "/*") == 0) {
      i = s.find("*/", i + 2);
      if (i == std::string_view::npos) break;
      i += 2;
    } else if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-') {
      const size_t start = i;
      while (i < s.size() && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_' || s[i] == '.' || s[i] == '-')) ++i;
      out.emplace_back(s.substr(start, i - start));
    } else {
      out.emplace_back(1, c);
      ++i;
    }
  }
  return out;
}

/// Parses the definitions compiled into the program; they are ours, so a parse failure is a broken invariant.
std::vector<StructDef> parse(std::string_view text) {
  const auto t = tokenize(text);
  std::vector<StructDef> structs;
  auto expect = [&](size_t i, const char* what) {
    if (i >= t.size() || t[i] != what) {
      const std::string why =
          std::string("expected '") + what + "' at token " + std::to_string(i) + " of the compiled-in definitions";
      internal_error(__FILE__, __LINE__, why.c_str());
    }
  };
  size_t i = 0;
  while (i < t.size()) {
    if (t[i] == "package") {
      i += 3;  // package NAME ;
      continue;
    }
    expect(i, "struct");
    StructDef s;
    s.name = t[i + 1];
    expect(i + 2, "{");
    i += 3;
    while (i < t.size() && t[i] != "}") {
      FieldDef f;
      f.type = t[i];
      if (const size_t dot = f.type.rfind('.'); dot != std::string::npos) f.type = f.type.substr(dot + 1);
      f.name = t[i + 1];
      i += 2;
      while (i < t.size() && t[i] == "[") {
        f.dims.push_back(t[i + 1]);
        expect(i + 2, "]");
        i += 3;
      }
      expect(i, ";");
      ++i;
      s.fields.push_back(std::move(f));
    }
    expect(i, "}");
    ++i;
    structs.push_back(std::move(s));
  }
  return structs;
}

struct Walker {
  std::span<const uint8_t> data;
  size_t pos = 0;
  const FieldVisitor& visit;
  const FlattenOptions& options;
  const RawFieldVisitor* raw = nullptr;  ///< walk(): primitives as bytes, columns without indices

  bool take(size_t n, const uint8_t*& p) {
    if (data.size() - pos < n) return false;
    p = data.data() + pos;
    pos += n;
    return true;
  }
  static uint64_t be(const uint8_t* p, size_t n) {
    uint64_t v = 0;
    for (size_t k = 0; k < n; ++k) v = (v << 8) | p[k];
    return v;
  }

  /// Bytes of one element of a fixed-size primitive type; 0 for strings and structs.
  static size_t fixed_size(const std::string& type) {
    if (type == "double" || type == "int64_t") return 8;
    if (type == "float" || type == "int32_t") return 4;
    if (type == "int16_t") return 2;
    if (type == "int8_t" || type == "byte" || type == "boolean") return 1;
    return 0;
  }

  /// One primitive; `value` receives its integer value (for array lengths). emit = false skips the visit.
  bool primitive(const FieldDef& f, const std::string& column, int64_t* value, bool emit) {
    const std::string& type = f.type;
    const uint8_t* p = nullptr;
    char buf[40];
    std::string text;
    if (raw != nullptr && (value == nullptr || type == "string" || type == "double" || type == "float")) {
      // walk(): the bytes (integers that may be lengths are read below)
      const size_t size = fixed_size(type);
      if (size == 0) {  // a string: its length with the NUL, then its bytes
        if (!take(4, p)) return false;
        const auto n = static_cast<uint32_t>(be(p, 4));
        if (n == 0 || !take(n, p)) return false;
        if (emit) (*raw)(column, f, {p, n - 1});
        return true;
      }
      if (!take(size, p)) return false;
      if (emit) (*raw)(column, f, {p, size});
      return true;
    }
    if (type == "double") {
      if (!take(8, p)) return false;
      const uint64_t bits = be(p, 8);
      double d;
      std::memcpy(&d, &bits, 8);
      // The shortest text that reads back as the same double (std::to_chars), several times faster than "%.17g".
      text.assign(buf, std::to_chars(buf, buf + sizeof(buf), d).ptr);
    } else if (type == "float") {
      if (!take(4, p)) return false;
      const auto bits = static_cast<uint32_t>(be(p, 4));
      float f;
      std::memcpy(&f, &bits, 4);
      text.assign(buf, std::to_chars(buf, buf + sizeof(buf), f).ptr);
    } else if (type == "string") {
      if (!take(4, p)) return false;
      const auto n = static_cast<uint32_t>(be(p, 4));  // with its NUL
      if (n == 0 || !take(n, p)) return false;
      text.assign(reinterpret_cast<const char*>(p), n - 1);
    } else {
      const size_t size = fixed_size(type);
      if (!take(size, p)) return false;
      const uint64_t word = be(p, size);
      const int shift = static_cast<int>(64 - 8 * size);
      // Sign-extended, but for byte: LCM's byte is unsigned (uint8_t in C++).
      const int64_t v = type == "byte" ? static_cast<int64_t>(word) : static_cast<int64_t>(word << shift) >> shift;
      if (value != nullptr) *value = v;
      if (raw != nullptr) {
        if (emit) (*raw)(column, f, {p, size});
        return true;
      }
      text = std::to_string(type == "boolean" ? (v != 0) : v);
    }
    if (emit) visit(column, text);
    return true;
  }

  bool element(const FieldDef& f, const std::string& column, int64_t* value, bool emit) {
    // A primitive first: find_struct scans every struct's name, too slow for every number of every message.
    if (fixed_size(f.type) == 0 && f.type != "string") {
      if (const StructDef* nested = find_struct(f.type)) return fields(*nested, column + ".", emit);
    }
    return primitive(f, column, value, emit);
  }

  /// Elements of dimensions dims[d..] of f, prefixed by column.
  bool array(const FieldDef& f, size_t d, const std::vector<int64_t>& sizes, const std::string& column, bool emit) {
    if (d == sizes.size()) return element(f, column, nullptr, emit);
    for (int64_t k = 0; k < sizes[d]; ++k) {
      if (!array(f, d + 1, sizes, emit && raw == nullptr ? column + "[" + std::to_string(k) + "]" : column, emit)) {
        return false;
      }
    }
    return true;
  }

  bool fields(const StructDef& s, const std::string& prefix, bool emit) {
    // Integer fields so far, for variable array lengths: a few per struct, so a scan, and no map built per message.
    std::vector<std::pair<const std::string*, int64_t>> ints;
    const auto length = [&ints](const std::string& name) {
      for (auto it = ints.rbegin(); it != ints.rend(); ++it) {
        if (*it->first == name) return it->second;
      }
      return int64_t{0};
    };
    for (const FieldDef& f : s.fields) {
      const std::string column = prefix + f.name;
      if (f.dims.empty()) {
        int64_t v = 0;
        if (!element(f, column, &v, emit)) return false;
        if (f.type != "double" && f.type != "float" && fixed_size(f.type) > 0) ints.emplace_back(&f.name, v);
        continue;
      }
      std::vector<int64_t> sizes;
      int64_t total = 1;
      for (const auto& dim : f.dims) {
        const int64_t n = std::isdigit(static_cast<unsigned char>(dim[0])) ? std::atoll(dim.c_str()) : length(dim);
        if (n < 0) return false;
        sizes.push_back(n);
        total *= n;
      }
      const bool keep =
          emit &&
          (raw != nullptr || (static_cast<size_t>(total) <= options.max_array && (f.type != "byte" || options.bytes)));
      if (const size_t size = fixed_size(f.type); (!keep || raw != nullptr) && size > 0) {  // in one step
        const uint8_t* p = nullptr;
        if (static_cast<uint64_t>(total) > (data.size() - pos) / size || !take(static_cast<size_t>(total) * size, p)) {
          return false;
        }
        if (keep) (*raw)(column, f, {p, static_cast<size_t>(total) * size});
        continue;
      }
      if (!array(f, 0, sizes, column, keep)) return false;
    }
    return true;
  }
};

}  // namespace

const std::vector<StructDef>& all_structs() {
  static const std::vector<StructDef> structs = parse(kLcmDefinitions);
  return structs;
}

const StructDef* find_struct(std::string_view name) {
  if (const size_t dot = name.rfind('.'); dot != std::string_view::npos) name = name.substr(dot + 1);
  for (const StructDef& s : all_structs()) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

bool flatten(const StructDef& def, std::span<const uint8_t> data, const FieldVisitor& visit,
             const FlattenOptions& options) {
  if (data.size() < 8) return false;
  Walker w{data, 8, visit, options};
  return w.fields(def, "", true);
}

bool walk(const StructDef& def, std::span<const uint8_t> data, const RawFieldVisitor& visit) {
  if (data.size() < 8) return false;
  static const FieldVisitor no_text;
  static const FlattenOptions options;
  Walker w{data, 8, no_text, options, &visit};
  return w.fields(def, "", true);
}

}  // namespace driftlab::lcmtypes
