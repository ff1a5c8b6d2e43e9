// A channel of an LCM log as columns, one per field of its messages, for the Python module's Log.read: numbers kept
// as numbers in native byte order, ready to become NumPy arrays without a copy. Messages are decoded by a plan
// compiled once per type (read_channel.cc's DecodePlan: a flat list of fixed-size copies, strings and loops, each
// with its destination column); lcmtypes/schema.h's walk, which the plan mirrors, is kept as the reference decode.
// An intact log is read forward through a buffer (read_intact_log), a damaged one through its mapping (EventTable).
// Thread-safety: plain functions on their own data; run without the GIL.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/log_event.h"
#include "core/mapped_file.h"
#include "core/result.h"

namespace driftlab::python {

/// Memory for a column: large blocks in transparent huge pages (2 MiB), so that filling them takes a page fault
/// (and a TLB entry) per 2 MiB rather than per 4 KiB; the first touch of fresh pages was a fifth of a read.
void* allocate_column(size_t bytes);
void free_column(void* p, size_t bytes) noexcept;

/// An allocator whose resize leaves new elements uninitialized: column buffers are sized once and then written,
/// so zero-filling them first would be a wasted pass over memory. Large buffers in huge pages (allocate_column).
template <typename T>
struct UninitializedAllocator : std::allocator<T> {
  using value_type = T;
  template <typename U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <typename U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  T* allocate(size_t n) { return static_cast<T*>(allocate_column(n * sizeof(T))); }
  void deallocate(T* p, size_t n) noexcept { free_column(p, n * sizeof(T)); }
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

using Bytes = std::vector<uint8_t, UninitializedAllocator<uint8_t>>;
using Int64s = std::vector<int64_t, UninitializedAllocator<int64_t>>;

/// A column's strings, in order: each string kept once while it recurs (a frame name, message after message, or
/// two taking turns), and an index to it per element, so that millions of them take 4 bytes each rather than a
/// std::string (32 bytes, fresh memory to fault in) each.
class Strings {
 public:
  size_t size() const { return index_.size(); }
  void reserve(size_t n) { index_.reserve(n); }
  /// The element's string as an index into distinct(), which holds it.
  uint32_t id(size_t element) const { return index_[element]; }
  const std::vector<std::string>& distinct() const { return distinct_; }

  void push_back(std::string_view s) {
    size_t hit = 0;
    while (hit < recent_.size() && !(recent_[hit] < distinct_.size() && distinct_[recent_[hit]] == s)) ++hit;
    if (hit == recent_.size()) {  // not among the last few: a new one, which pushes the oldest out
      hit = recent_.size() - 1;
      recent_[hit] = static_cast<uint32_t>(distinct_.size());
      distinct_.emplace_back(s);
    }
    std::rotate(recent_.begin(), recent_.begin() + static_cast<std::ptrdiff_t>(hit),
                recent_.begin() + static_cast<std::ptrdiff_t>(hit) + 1);  // the latest first
    index_.push_back(recent_[0]);
  }
  /// The first n elements kept (n <= size()).
  void resize(size_t n) { index_.resize(n); }
  void clear() {
    index_.clear();
    distinct_.clear();
    recent_.fill(UINT32_MAX);
  }

 private:
  std::vector<uint32_t, UninitializedAllocator<uint32_t>> index_;
  std::vector<std::string> distinct_;
  std::array<uint32_t, 4> recent_ = {UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX};  // distinct_, latest first
};

/// One field of a channel's messages: every message's elements, in message order.
struct Column {
  std::string name;                  ///< dotted path without indices: "header.utime", "ranges", "pose.position.x"
  char kind = 'f';                   ///< NumPy's kind: 'f' float, 'i' signed integer, 'u' byte, 'b' boolean, 'O' string
  size_t item_bytes = 8;             ///< bytes of one element (0 for strings)
  std::vector<size_t> dims;          ///< the field's fixed dimensions (empty: a scalar, or a variable-length array)
  Bytes data;                        ///< the elements, native byte order
  Strings strings;                   ///< kind 'O'
  Int64s counts;                     ///< elements of each message; empty when every message holds fixed_count
  int64_t fixed_count = -1;          ///< elements of every message when counts is empty
};

struct Channel {
  std::string type;              ///< "driftlab.odometry_t"
  Int64s arrival;                ///< the log's receive time of each message [us]
  std::vector<Column> columns;   ///< in the order of the message's fields
  int64_t skipped = 0;           ///< messages of another type, or cut short, left out [count]
};

/// An LCM log mapped once (its pages mapped in up front, and kept), with where each channel's events are, from
/// one pass over it: a read then visits only its channels' events, and no page of the log is faulted in twice.
/// Immutable once built: may be shared between reads and threads.
class EventTable {
 public:
  /// Errors: the log cannot be read (as LogReader::open's).
  static Result<std::shared_ptr<const EventTable>> build(const std::string& path);

  const std::string& path() const { return path_; }
  /// The offsets of the channel's intact events, in file order (nullptr for a channel with none).
  const std::vector<uint64_t>* offsets(const std::string& channel) const;
  /// The event at one of offsets().
  Event event_at(uint64_t offset) const;
  /// Asks the CPU for the first lines of the event at one of offsets(), to be read soon.
  void prefetch(uint64_t offset) const;

  EventTable(std::string path, MappedFile mapped) : path_(std::move(path)), mapped_(std::move(mapped)) {}

 private:
  std::string path_;
  MappedFile mapped_;
  std::unordered_map<std::string, std::vector<uint64_t>> offsets_;
};

/// Reads every message of each of `channels` (name, the index's count, which sizes the columns) from the table's
/// log, in that order. Messages of another type than the channel's first, or cut short, are left out.
/// Errors: a channel whose messages are of no driftlab type.
Result<std::vector<Channel>> read_channels(const EventTable& log,
                                           const std::vector<std::pair<std::string, int64_t>>& channels);

/// read_channels() of an intact log at path (every event where the one before it ended: the events LogReader
/// finds, none with a problem), without an EventTable: `threads` passes over the file at once, each through a
/// buffer read with pread(2), each decoding its share of the channels (shared by their `bytes`, the index's).
/// nullopt when the log is not intact (read it through an EventTable: it reads past damage as LogReader does) or
/// cannot be read. Errors: as read_channels().
Result<std::optional<std::vector<Channel>>> read_intact_log(
    const std::string& path, const std::vector<std::pair<std::string, int64_t>>& channels,
    const std::vector<uint64_t>& bytes, size_t threads);

/// read_channels() of the log at path through lcmtypes::walk, message by message and field by field, in one
/// LogReader pass: the reference the plans are tested against (the same columns, in the same order, with the same
/// elements). Slow. Errors: also, the log cannot be read.
Result<std::vector<Channel>> read_channels_reference(const std::string& path,
                                                     const std::vector<std::pair<std::string, int64_t>>& channels);

}  // namespace driftlab::python
