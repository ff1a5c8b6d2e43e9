// Finds events in a byte range, resynchronising on the sync word after corruption.
// Internal to core: use LogReader.
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include "core/log_event.h"

namespace driftlab::internal {

class EventScanner {
 public:
  /// bytes must outlive the scanner. on_problem may be null.
  EventScanner(std::span<const uint8_t> bytes, const ProblemCallback* on_problem)
      : bytes_(bytes), on_problem_(on_problem) {}

  /// The next intact event at or after position(); false at the end of the bytes.
  bool next(Event& out);

  uint64_t position() const { return pos_; }
  /// Continue from offset (which should be the start of an event, e.g. from an index).
  void set_position(uint64_t offset) { pos_ = offset < bytes_.size() ? offset : bytes_.size(); }
  /// No event that starts at or after offset is read (next() is false once position() reaches it).
  void stop_at(uint64_t offset) { limit_ = offset; }
  /// Where an event seems to start at or after offset (one that chains to the next, as after corruption).
  std::optional<uint64_t> event_at_or_after(uint64_t offset) const { return resync(offset); }
  uint64_t problems() const { return problems_; }

 private:
  struct Header {
    int32_t channel_len;
    int32_t data_len;
    uint64_t end;  // offset one past the event
  };
  /// Parses the header at offset: sync word, sane lengths, and the event ends inside the bytes.
  std::optional<Header> plausible_event_at(uint64_t offset) const;
  bool sync_at(uint64_t offset) const;
  /// First offset >= from (and < limit) where a plausible event starts.
  std::optional<uint64_t> find_event(uint64_t from, uint64_t limit) const;
  /// First offset in [from, limit) of a plausible event that ends at the end of the bytes or at a sync word.
  std::optional<uint64_t> find_chained_event(uint64_t from, uint64_t limit) const;
  /// Where to resume reading after a problem at from - 1.
  std::optional<uint64_t> resync(uint64_t from) const;
  void report(uint64_t offset, ProblemKind kind, std::string detail);

  std::span<const uint8_t> bytes_;
  const ProblemCallback* on_problem_;
  uint64_t pos_ = 0;
  uint64_t limit_ = UINT64_MAX;
  uint64_t problems_ = 0;
  bool empty_reported_ = false;
};

}  // namespace driftlab::internal
