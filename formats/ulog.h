// PX4 flight logs (ULog, .ulg), as PX4's "ULog File Format" specifies them: a header (magic, version, start
// time), definitions (flag bits, message formats, information fields, parameters and their defaults), then data
// (subscriptions, data messages, logged strings, parameter changes, sync and dropout records), and, when the
// flag bits say so, appended data sections read in turn. Little-endian throughout; times are microseconds of the
// flight controller's boot clock.
//
// The reader is bounds-checked over the bytes (a file, read forward through a window of it, or memory): a message
// that does not parse is reported once with its byte offset, and reading goes on at the next message that parses (a
// sync record, or a message whose header and content fit what the file defined, followed by another such header or
// the end); a file cut short keeps every message before the cut. The spans a callback is given hold only during the
// call. Thread-safety: one reader per thread.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "core/mapped_file.h"
#include "core/result.h"

namespace driftlab::formats {

enum class UlogType : uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat,
  kDouble,
  kBool,
  kChar
};

/// A message format resolved into its primitive fields, flattened: a nested field's name is "outer.inner", an
/// element of an array of nested types "outer[2].inner"; an array of primitives is one field with its count.
/// `_padding` fields take their bytes and are left out.
struct UlogLayout {
  struct Field {
    std::string name;
    UlogType type = UlogType::kUint8;
    uint32_t offset = 0;  ///< [bytes] from the start of the message's data (after its msg_id)
    uint32_t count = 0;   ///< 0 for a single value, n for type[n]
  };
  std::string name;
  uint32_t size = 0;          ///< [bytes], padding included
  uint32_t size_written = 0;  ///< [bytes] without the trailing _padding fields, which PX4 does not write
  std::vector<Field> fields;
  /// The format's definition and those of the types it nests, each as the file states it ("name:type field;..."),
  /// one a line, its own first.
  std::string definition;
  int64_t timestamp_offset = -1;                    ///< the offset of its uint64_t `timestamp`, -1 when it has none
  std::unordered_map<std::string, uint32_t> index;  ///< field name -> its place in fields (for find)

  const Field* find(std::string_view field) const;
  /// The value of a numeric field (element i of an array) as a double; NaN when the field is missing, is not a
  /// number, or lies outside data.
  double number(std::span<const uint8_t> data, std::string_view field, uint32_t i = 0) const;
  /// A uint64_t field's exact value (PX4's times), nullopt when the format has none or data ends before it.
  std::optional<uint64_t> u64(std::span<const uint8_t> data, std::string_view field) const;
  /// The same of a field found before (nullptr: a field the format does not have).
  double number(std::span<const uint8_t> data, const Field* field, uint32_t i = 0) const;
  std::optional<uint64_t> u64(std::span<const uint8_t> data, const Field* field) const;
};

/// A ULog time [us] as driftlab's int64_t microseconds: a hostile value past int64_t's end is held at its end.
inline int64_t ulog_utime(uint64_t us) {
  return us > static_cast<uint64_t>(INT64_MAX) ? INT64_MAX : static_cast<int64_t>(us);
}

/// A subscription (ULog's 'A' record): the topic instance a data message's msg_id stands for.
struct UlogSubscription {
  uint16_t msg_id = 0;
  uint8_t multi_id = 0;
  std::string name;
  std::shared_ptr<const UlogLayout> layout;  ///< null when the format does not resolve (see layout_error)
  std::string layout_error;
};

struct UlogData {
  const UlogSubscription* subscription = nullptr;
  uint64_t timestamp = 0;            ///< its `timestamp` field; the latest read before it when it has none
  std::span<const uint8_t> payload;  ///< the message's bytes after its msg_id (trailing padding not written)
  uint64_t offset = 0;               ///< of the record in the file
};

struct UlogLogged {
  uint8_t level = 0;  ///< as written: '0'..'7' (ASCII, PX4) or 0..7
  bool tagged = false;
  uint16_t tag = 0;
  uint64_t timestamp = 0;
  std::string_view text;
  uint64_t offset = 0;
};

/// An information field ('I', 'M'), a parameter ('P') or a parameter's default ('Q').
struct UlogValue {
  char kind = 'I';        ///< 'I', 'M', 'P' or 'Q'
  std::string_view type;  ///< "int32_t", "float", "char[12]"
  std::string_view key;
  std::span<const uint8_t> value;
  bool continued = false;       ///< 'M': continues the previous value of the key
  uint8_t default_types = 0;    ///< 'Q'
  bool in_definitions = false;  ///< read before the data section (a parameter's initial value)
  uint64_t time = 0;            ///< the header's start time in the definitions, else the latest timestamp read
  uint64_t offset = 0;
};

struct UlogDropout {
  uint64_t timestamp = 0;  ///< the latest data timestamp read before it (the header's start time before any)
  uint16_t duration_ms = 0;
  uint64_t offset = 0;
};

class UlogReader {
 public:
  /// Maps path. An error when it cannot be read or is not a ULog (its first bytes say what it is).
  static Result<UlogReader> open(const std::string& path);
  /// A log in memory (kept by the reader): for tests and fuzzing.
  static Result<UlogReader> from_memory(std::vector<uint8_t> bytes);
  /// Whether these first bytes are a ULog's header.
  static bool looks_like(std::span<const uint8_t> head);

  struct Callbacks {
    std::function<void(const UlogData&)> data;
    std::function<void(const UlogSubscription&)> subscription;
    std::function<void(const UlogLogged&)> logged;
    std::function<void(const UlogValue&)> value;
    std::function<void(const UlogDropout&)> dropout;
    /// One line per problem (a stretch that does not parse, a cut, a format that does not resolve), without the
    /// file's name: "at byte 1234: ...".
    std::function<void(uint64_t offset, const std::string& what)> problem;
  };
  /// Reads the whole log in file order. An Error only for what makes the rest unreadable: a header that is not a
  /// ULog's, or an incompatible flag this reader does not know.
  Status read(const Callbacks& callbacks);

  uint8_t version() const { return version_; }
  uint64_t start_us() const { return start_us_; }
  /// After read(): the largest data timestamp (the start time when there is none), as pyulog's last_timestamp.
  uint64_t last_us() const { return last_us_; }
  /// After read(): records of types this reader does not know, skipped whole, by type letter.
  const std::map<char, int64_t>& unknown_types() const { return unknown_types_; }

 private:
  UlogReader() = default;

  MappedFile file_;  ///< its header checked when opened; read() reads path_ again through a descriptor
  std::string path_;
  std::vector<uint8_t> memory_;
  bool in_memory_ = false;
  uint8_t version_ = 0;
  uint64_t start_us_ = 0;
  uint64_t last_us_ = 0;
  std::map<char, int64_t> unknown_types_;
};

/// Resolves format `name` against the formats of a file (name -> "name:type field;..." as written): nested
/// types, arrays, padding. An error naming the problem for an unknown or recursive type, a field that does not
/// parse, or a size larger than a ULog message can hold (65535 bytes).
Result<UlogLayout> resolve_ulog_format(const std::map<std::string, std::string, std::less<>>& formats,
                                       const std::string& name);

}  // namespace driftlab::formats
