#include "lcmtypes/validate.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"

namespace driftlab::lcmtypes {
namespace {

/// One field of a struct, compiled: how to step over it and what to remember of it.
struct Op {
  enum Kind { kFixed, kString, kStruct } kind = kFixed;
  size_t size = 0;               ///< kFixed: bytes per element
  bool is_signed = true;         ///< kFixed: an integer is sign-extended (all but byte)
  bool is_float = false;         ///< kFixed: a double or float
  const struct Plan* nested = nullptr;  ///< kStruct
  int slot = -1;                 ///< a scalar integer kept for later lengths, or -1
  struct Dim {
    int64_t constant = 0;
    int slot = -1;               ///< the length is that earlier integer field
  };
  std::vector<Dim> dims;
  std::string name;
};

struct Plan {
  std::vector<Op> ops;
  int slots = 0;
  /// The same layout for checking alone, faster to walk: single nested structs inlined, and runs of fixed-size
  /// fields that no length refers to merged into one (an IMU message: 12 steps, not 40). Its errors name a run,
  /// not a field, so a message it refuses is walked again by `ops` for the reason. Null when it would need more
  /// than kMaxSlots slots.
  std::unique_ptr<Plan> flat;
};
constexpr int kMaxSlots = 32;  ///< integer fields per struct; ours have far fewer

/// Appends plan's ops to out as Plan::flat has them, plan's slots numbered from `base` in out (out.slots counts
/// them). False when they exceed kMaxSlots.
bool flatten_into(const Plan& plan, int base, Plan& out) {
  for (const Op& op : plan.ops) {
    Op o = op;
    if (o.slot >= 0) o.slot += base;
    for (auto& d : o.dims) {
      if (d.slot >= 0) d.slot += base;
    }
    if (o.kind == Op::kStruct && o.dims.empty()) {
      const int nested_base = out.slots;
      out.slots += o.nested->slots;
      if (out.slots > kMaxSlots || !flatten_into(*o.nested, nested_base, out)) return false;
      continue;
    }
    if (o.kind == Op::kStruct && o.nested->flat != nullptr) o.nested = o.nested->flat.get();
    const bool constant = std::all_of(o.dims.begin(), o.dims.end(), [](const Op::Dim& d) { return d.slot < 0; });
    if (o.kind == Op::kFixed && o.slot < 0 && constant) {
      size_t bytes = o.size;
      for (const auto& d : o.dims) bytes *= static_cast<size_t>(d.constant);
      if (bytes == 0) continue;
      if (!out.ops.empty() && out.ops.back().kind == Op::kFixed && out.ops.back().slot < 0 &&
          out.ops.back().dims.empty()) {
        out.ops.back().size += bytes;
        continue;
      }
      o.size = bytes;
      o.dims.clear();
    }
    out.ops.push_back(std::move(o));
  }
  return true;
}

size_t fixed_size(const std::string& type) {
  if (type == "double" || type == "int64_t") return 8;
  if (type == "float" || type == "int32_t") return 4;
  if (type == "int16_t") return 2;
  if (type == "int8_t" || type == "byte" || type == "boolean") return 1;
  return 0;
}

class Plans {
 public:
  const Plan* find(int64_t fingerprint) {
    // A log interleaves a few types (IMU, odometry, poses, scans): this thread's last answers, without the lock.
    struct Recent {
      int64_t fingerprint = 0;
      const Plan* plan = nullptr;
    };
    thread_local std::array<Recent, 8> recent{};
    thread_local size_t next_slot = 0;
    for (const Recent& r : recent) {
      if (r.fingerprint == fingerprint && r.plan != nullptr) return r.plan;
    }
    const Plan* p = nullptr;
    {
      std::lock_guard lock(mutex_);
      if (auto it = by_fingerprint_.find(fingerprint); it != by_fingerprint_.end()) {
        p = it->second;
      } else {
        const char* name = type_name(fingerprint);
        p = name != nullptr ? compile(name) : nullptr;
        by_fingerprint_[fingerprint] = p;
      }
    }
    recent[next_slot] = {fingerprint, p};
    next_slot = (next_slot + 1) % recent.size();
    return p;
  }

 private:
  const Plan* compile(const std::string& name) {
    const StructDef* def = find_struct(name);
    if (def == nullptr) return nullptr;
    if (auto it = by_name_.find(def->name); it != by_name_.end()) return it->second.get();
    auto plan = std::make_unique<Plan>();
    std::map<std::string, int> slot_of;
    for (const FieldDef& f : def->fields) {
      Op op;
      op.name = f.name;
      if (f.type == "string") {
        op.kind = Op::kString;
      } else if (const size_t size = fixed_size(f.type)) {
        op.kind = Op::kFixed;
        op.size = size;
        op.is_signed = f.type != "byte";
        op.is_float = f.type == "double" || f.type == "float";
      } else {
        op.kind = Op::kStruct;
        op.nested = compile(f.type);
        if (op.nested == nullptr) return nullptr;  // not reached: our definitions are complete
      }
      for (const auto& d : f.dims) {
        Op::Dim dim;
        if (std::isdigit(static_cast<unsigned char>(d[0]))) {
          dim.constant = std::atoll(d.c_str());
        } else {
          dim.slot = slot_of.at(d);  // lcm-gen refuses a length that is not an earlier integer field
        }
        op.dims.push_back(dim);
      }
      if (op.kind == Op::kFixed && op.dims.empty() && !op.is_float && plan->slots < kMaxSlots) {
        op.slot = plan->slots++;
        slot_of[f.name] = op.slot;
      }
      plan->ops.push_back(std::move(op));
    }
    auto flat = std::make_unique<Plan>();
    flat->slots = plan->slots;
    if (flatten_into(*plan, 0, *flat)) plan->flat = std::move(flat);
    const Plan* p = plan.get();
    by_name_[def->name] = std::move(plan);
    return p;
  }

  std::mutex mutex_;
  std::map<int64_t, const Plan*> by_fingerprint_;
  std::map<std::string, std::unique_ptr<Plan>> by_name_;
};

Plans& plans() {
  static Plans p;
  return p;
}

int64_t read_int(const uint8_t* p, size_t n, bool is_signed) {
  uint64_t v = 0;
  for (size_t k = 0; k < n; ++k) v = (v << 8) | p[k];
  if (!is_signed || n == 8) return static_cast<int64_t>(v);
  const int shift = static_cast<int>(64 - 8 * n);
  return static_cast<int64_t>(v << shift) >> shift;
}

/// The first of n floating-point numbers of `size` bytes at p that is NaN or infinite, or -1.
int64_t first_non_finite(const uint8_t* p, uint64_t n, size_t size, double* value) {
  for (uint64_t k = 0; k < n; ++k, p += size) {
    const uint64_t bits = static_cast<uint64_t>(read_int(p, size, false));
    const double v = size == 8 ? std::bit_cast<double>(bits) : std::bit_cast<float>(static_cast<uint32_t>(bits));
    if (!std::isfinite(v)) {
      *value = v;
      return static_cast<int64_t>(k);
    }
  }
  return -1;
}

std::string number_text(double v) { return std::isnan(v) ? "nan" : v > 0 ? "inf" : "-inf"; }

/// Steps over one struct's encoding from pos; on failure says why in *why. With non_finite, also names there the
/// first NaN or infinite number of a scalar or a fixed-size array ("x = nan", "pose_covariance[3] = inf") unless
/// it already holds one.
bool walk(const Plan& plan, std::span<const uint8_t> data, size_t& pos, std::string* why, int depth,
          std::string* non_finite = nullptr) {
  if (depth > 16) {  // our types nest a few levels; a plan deeper than this is a broken invariant
    *why = "nested too deeply";
    return false;
  }
  int64_t slots[kMaxSlots] = {};
  for (const Op& op : plan.ops) {
    const size_t left = data.size() - pos;
    // Elements of the field: the product of its dimensions, each non-negative, none beyond what bytes could hold.
    uint64_t count = 1;
    for (const auto& dim : op.dims) {
      const int64_t n = dim.slot >= 0 ? slots[static_cast<size_t>(dim.slot)] : dim.constant;
      if (n < 0) {
        *why = op.name + ": length " + std::to_string(n);
        return false;
      }
      if (n != 0 && count > static_cast<uint64_t>(left) / static_cast<uint64_t>(n)) {  // elements take >= 1 byte
        *why = op.name + ": length " + std::to_string(n) + " does not fit in the " + std::to_string(left) +
               " bytes left";
        return false;
      }
      count *= static_cast<uint64_t>(n);
    }
    switch (op.kind) {
      case Op::kFixed: {
        if (count > left / op.size) {
          *why = op.name + ": the message ends inside it";
          return false;
        }
        if (op.slot >= 0) slots[static_cast<size_t>(op.slot)] = read_int(data.data() + pos, op.size, op.is_signed);
        // Variable-length arrays of numbers are samples (ranges, points), where NaN and inf say "no return".
        if (non_finite != nullptr && non_finite->empty() && op.is_float &&
            std::all_of(op.dims.begin(), op.dims.end(), [](const Op::Dim& d) { return d.slot < 0; })) {
          double v = 0;
          if (const int64_t k = first_non_finite(data.data() + pos, count, op.size, &v); k >= 0) {
            *non_finite = op.name + (op.dims.empty() ? "" : "[" + std::to_string(k) + "]") + " = " + number_text(v);
          }
        }
        pos += static_cast<size_t>(count) * op.size;
        break;
      }
      case Op::kString:
        for (uint64_t k = 0; k < count; ++k) {
          if (data.size() - pos < 4) {
            *why = op.name + ": the message ends inside it";
            return false;
          }
          const int64_t n = read_int(data.data() + pos, 4, true);  // length with the NUL
          pos += 4;
          if (n < 1 || static_cast<uint64_t>(n) > data.size() - pos) {
            *why = op.name + ": string length " + std::to_string(n) +
                   (n < 1 ? "" : " does not fit in the " + std::to_string(data.size() - pos) + " bytes left");
            return false;
          }
          pos += static_cast<size_t>(n);
        }
        break;
      case Op::kStruct:
        for (uint64_t k = 0; k < count; ++k) {
          const bool found_before = non_finite != nullptr && !non_finite->empty();
          if (!walk(*op.nested, data, pos, why, depth + 1, non_finite)) {
            *why = op.name + "." + *why;
            return false;
          }
          if (non_finite != nullptr && !found_before && !non_finite->empty()) {
            *non_finite = op.name + (op.dims.empty() ? "" : "[" + std::to_string(k) + "]") + "." + *non_finite;
          }
        }
        break;
    }
  }
  return true;
}

std::optional<std::string> check(std::span<const uint8_t> data, const Plan& plan, std::string* non_finite = nullptr) {
  std::string why;
  size_t pos = 8;
  if (non_finite == nullptr && plan.flat != nullptr && walk(*plan.flat, data, pos, &why, 0) && pos == data.size()) {
    return std::nullopt;  // well formed; a refusal is walked again field by field for its reason
  }
  pos = 8;
  why.clear();
  if (!walk(plan, data, pos, &why, 0, non_finite)) return why;
  if (pos != data.size()) {
    return std::to_string(data.size() - pos) + " bytes after the end of its type";
  }
  return std::nullopt;
}

int64_t fingerprint_of(std::span<const uint8_t> data) {
  if (data.size() < 8) return 0;
  return read_int(data.data(), 8, true);
}

}  // namespace

std::optional<std::string> layout_problem(std::span<const uint8_t> data) {
  if (data.size() < 8) return std::to_string(data.size()) + " bytes, shorter than a type fingerprint";
  const Plan* plan = plans().find(fingerprint_of(data));
  if (plan == nullptr) return std::nullopt;
  return check(data, *plan);
}

std::optional<std::string> non_finite(std::span<const uint8_t> data) {
  if (data.size() < 8) return std::nullopt;
  const Plan* plan = plans().find(fingerprint_of(data));
  if (plan == nullptr) return std::nullopt;
  std::string found;
  if (check(data, *plan, &found).has_value() || found.empty()) return std::nullopt;
  return found;
}

bool well_formed(std::span<const uint8_t> data, int64_t fingerprint) {
  if (data.size() < 8 || fingerprint_of(data) != fingerprint) return false;
  const Plan* plan = plans().find(fingerprint);
  return plan != nullptr && !check(data, *plan).has_value();
}

}  // namespace driftlab::lcmtypes
