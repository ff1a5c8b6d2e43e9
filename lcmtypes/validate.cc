#include "lcmtypes/validate.h"

#include <cctype>
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
};
constexpr int kMaxSlots = 32;  ///< integer fields per struct; ours have far fewer

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
    // Messages come in runs of one type: the last answer of this thread, without the lock.
    thread_local int64_t last_fingerprint = 0;
    thread_local const Plan* last_plan = nullptr;
    if (fingerprint == last_fingerprint && last_plan != nullptr) return last_plan;
    std::lock_guard lock(mutex_);
    if (auto it = by_fingerprint_.find(fingerprint); it != by_fingerprint_.end()) {
      last_fingerprint = fingerprint;
      last_plan = it->second;
      return it->second;
    }
    const char* name = type_name(fingerprint);
    const Plan* p = name != nullptr ? compile(name) : nullptr;
    by_fingerprint_[fingerprint] = p;
    last_fingerprint = fingerprint;
    last_plan = p;
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
      if (op.kind == Op::kFixed && op.dims.empty() && f.type != "double" && f.type != "float" &&
          plan->slots < kMaxSlots) {
        op.slot = plan->slots++;
        slot_of[f.name] = op.slot;
      }
      plan->ops.push_back(std::move(op));
    }
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

/// Steps over one struct's encoding from pos; on failure says why in *why.
bool walk(const Plan& plan, std::span<const uint8_t> data, size_t& pos, std::string* why, int depth) {
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
          if (!walk(*op.nested, data, pos, why, depth + 1)) {
            *why = op.name + "." + *why;
            return false;
          }
        }
        break;
    }
  }
  return true;
}

std::optional<std::string> check(std::span<const uint8_t> data, const Plan& plan) {
  std::string why;
  size_t pos = 8;
  if (!walk(plan, data, pos, &why, 0)) return why;
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

bool well_formed(std::span<const uint8_t> data, int64_t fingerprint) {
  if (data.size() < 8 || fingerprint_of(data) != fingerprint) return false;
  const Plan* plan = plans().find(fingerprint);
  return plan != nullptr && !check(data, *plan).has_value();
}

}  // namespace driftlab::lcmtypes
