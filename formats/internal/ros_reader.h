// One reader for ROS 1 serialization and CDR (ROS 2), shared by the mapped decoders (ros_messages.cc) and the
// definition-driven walker (ros_definition.cc).
// ROS 1: little endian, packed, strings and arrays prefixed with a uint32 length. CDR (OMG XCDR1, what rosbag2
// stores): a 4-byte encapsulation header giving the byte order, every primitive aligned to its size counted from
// the end of that header, strings prefixed with a length that includes their terminating NUL. Written by hand
// rather than with Fast-CDR (Debian's libfastcdr 1.0): a bounds-checked reader over a span that reports the first
// problem as a value is shorter than wrapping Fast-CDR's FastBuffer and catching its exceptions per field, it
// reads ROS 1 serialization too, and it never allocates for a length the data cannot hold.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "formats/ros_messages.h"

namespace driftlab::formats::internal {

class Reader {
 public:
  Reader(std::span<const uint8_t> data, Serialization s) : data_(data), cdr_(s == Serialization::kCdr) {
    if (!cdr_) return;
    // Encapsulation: 0x00 0x00 big-endian CDR, 0x00 0x01 little-endian (0x02/0x03: the PL_CDR variants).
    if (data.size() < 4 || data[0] != 0 || data[1] > 3) {
      fail("no CDR encapsulation header");
      return;
    }
    swap_ = (data[1] & 1) == 0;
    origin_ = pos_ = 4;
  }

  bool ok() const { return error_.empty(); }
  bool cdr() const { return cdr_; }
  size_t pos() const { return pos_; }
  const std::string& error() const { return error_; }
  size_t remaining() const { return data_.size() - pos_; }
  /// Whether the message ended where its type does (CDR may pad to its alignment).
  bool at_end() const { return cdr_ ? remaining() < 8 : remaining() == 0; }

  template <typename T>
  T get() {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    if (!need(sizeof(T))) return T{};
    T v;
    std::memcpy(&v, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    if (swap_ && sizeof(T) > 1) v = swapped(v);
    return v;
  }
  /// A fixed-size array.
  template <typename T>
  void get(T* out, size_t n) {
    for (size_t i = 0; i < n; ++i) out[i] = get<T>();
  }
  /// A sequence's length, checked against what is left (each element at least min_element_bytes).
  uint32_t count(size_t min_element_bytes) {
    const uint32_t n = get<uint32_t>();
    if (ok() && min_element_bytes > 0 && n > remaining() / min_element_bytes) {
      fail("a sequence of " + std::to_string(n) + " elements in " + std::to_string(remaining()) + " bytes");
      return 0;
    }
    return n;
  }
  std::string str() {
    uint32_t n = count(1);
    if (!ok()) return {};
    std::string s(reinterpret_cast<const char*>(data_.data() + pos_), n);
    pos_ += n;
    if (cdr_ && !s.empty() && s.back() == '\0') s.pop_back();  // CDR counts the NUL
    return s;
  }
  std::span<const uint8_t> bytes(size_t n) {
    if (!need(n)) return {};
    auto s = data_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  /// builtin_interfaces/Time (ROS 2: int32 sec, uint32 nanosec) or ROS 1 time (uint32, uint32), in microseconds.
  int64_t time_us() {
    const int64_t sec = cdr_ ? int64_t{get<int32_t>()} : int64_t{get<uint32_t>()};
    const int64_t nsec = get<uint32_t>();
    return sec * 1'000'000 + nsec / 1000;
  }
  /// CDR: skips to the next multiple of n bytes after the encapsulation header (ROS 1 packs: nothing).
  void align(size_t n) {
    if (!cdr_ || n <= 1) return;
    const size_t off = (pos_ - origin_) % n;
    if (off != 0) pos_ = std::min(data_.size(), pos_ + (n - off));
  }
  void fail(std::string what) {
    if (error_.empty()) error_ = std::move(what);
    pos_ = data_.size();
  }
  /// header.seq for messages that carry none.
  int64_t fallback_seq = 0;
  /// A buffer a large converted message may take the memory of (convert_ros_message's `reuse`), or nullptr.
  std::vector<uint8_t>* reuse = nullptr;

 private:
  template <typename T>
  static T swapped(T v) {
    using U = std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
    U u;
    std::memcpy(&u, &v, sizeof(T));
    if constexpr (sizeof(T) == 2) u = __builtin_bswap16(u);
    if constexpr (sizeof(T) == 4) u = __builtin_bswap32(u);
    if constexpr (sizeof(T) == 8) u = __builtin_bswap64(u);
    std::memcpy(&v, &u, sizeof(T));
    return v;
  }
  bool need(size_t n) {
    if (!ok()) return false;
    if (remaining() < n) {
      fail("ends inside the message (" + std::to_string(data_.size()) + " bytes)");
      return false;
    }
    return true;
  }

  std::span<const uint8_t> data_;
  size_t pos_ = 0;
  size_t origin_ = 0;
  bool cdr_ = false;
  bool swap_ = false;
  std::string error_;
};

}  // namespace driftlab::formats::internal
