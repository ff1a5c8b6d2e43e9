// The driftlab message definitions at run time: every lcmtypes/*.lcm is compiled into the program and parsed
// here, so a message can be walked field by field without its generated class (as lcm-spy does with Java's
// reflection). `driftlab export csv` flattens any driftlab message into columns with it.
// Thread-safety: read-only after the first call, which is thread-safe (a function-local static).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace driftlab::lcmtypes {

struct FieldDef {
  std::string type;               ///< a primitive ("int32_t", "double", "string", ...) or a struct's short name
  std::string name;
  std::vector<std::string> dims;  ///< per dimension: a number, or the name of an earlier integer field
};

struct StructDef {
  std::string name;  ///< short name, "imu_t"
  std::vector<FieldDef> fields;
};

/// Every struct of lcmtypes/*.lcm.
const std::vector<StructDef>& all_structs();
/// The struct of this short name ("imu_t") or full name ("driftlab.imu_t"), or nullptr.
const StructDef* find_struct(std::string_view name);

/// One value of a flattened message: its column (a dotted path with indices: "header.utime", "ranges[3]") and
/// its text (numbers as C's %.17g for doubles, %.9g for floats; strings as they are).
using FieldVisitor = std::function<void(const std::string& column, const std::string& value)>;

struct FlattenOptions {
  size_t max_array = 1024;  ///< arrays with more elements than this are left out (their length field stays)
  bool bytes = false;       ///< byte arrays (image data) are left out unless set
};

/// Walks an encoded message (fingerprint first) of type `def` and calls visit for every primitive, in order.
/// False when the data is shorter than the message claims (what was visited stays visited).
bool flatten(const StructDef& def, std::span<const uint8_t> data, const FieldVisitor& visit,
             const FlattenOptions& options = {});

/// One primitive of a message as its bytes, for readers that keep numbers as numbers (the Python module): its
/// column without indices ("header.utime", "ranges", "poses.position.x"), its field, and its big-endian bytes: an
/// array of fixed-size primitives (any length, bytes too) in one call, each element of other arrays (strings,
/// structs' fields) in a call of its own, a string without its NUL.
using RawFieldVisitor =
    std::function<void(const std::string& column, const FieldDef& field, std::span<const uint8_t> bytes)>;

/// Walks an encoded message (fingerprint first) of type `def` as flatten() does, calling visit with the bytes of
/// every primitive. False when the data is shorter than the message claims.
bool walk(const StructDef& def, std::span<const uint8_t> data, const RawFieldVisitor& visit);

}  // namespace driftlab::lcmtypes
