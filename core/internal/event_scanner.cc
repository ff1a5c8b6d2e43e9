#include "core/internal/event_scanner.h"

#include <cstring>
#include <string>

#include "core/log_format.h"

namespace driftlab {

const char* to_string(ProblemKind kind) {
  switch (kind) {
    case ProblemKind::kEmptyFile: return "empty_file";
    case ProblemKind::kGarbage: return "garbage";
    case ProblemKind::kTruncatedEvent: return "truncated_event";
    case ProblemKind::kBadLength: return "bad_length";
    case ProblemKind::kBadChannelLength: return "bad_channel_length";
  }
  return "unknown";
}

namespace internal {
namespace {
constexpr uint8_t kSyncBytes[4] = {0xED, 0xA1, 0xDA, 0x01};

std::string skipped(uint64_t from, std::optional<uint64_t> to, uint64_t size) {
  if (!to) return "; no further event, " + std::to_string(size - from) + " bytes to the end of the file ignored";
  return "; skipped " + std::to_string(*to - from) + " bytes to the next event at offset " + std::to_string(*to);
}
}  // namespace

bool EventScanner::sync_at(uint64_t offset) const {
  return bytes_.size() >= 4 && offset <= bytes_.size() - 4 && logfmt::load_be32(bytes_.data() + offset) == logfmt::kSyncWord;
}

std::optional<EventScanner::Header> EventScanner::plausible_event_at(uint64_t offset) const {
  const uint64_t size = bytes_.size();
  if (offset > size || size - offset < logfmt::kEventHeaderSize || !sync_at(offset)) return std::nullopt;
  const uint8_t* p = bytes_.data() + offset;
  Header h{static_cast<int32_t>(logfmt::load_be32(p + 20)), static_cast<int32_t>(logfmt::load_be32(p + 24)), 0};
  if (h.channel_len <= 0 || h.channel_len > logfmt::kMaxChannelLength || h.data_len < 0) return std::nullopt;
  h.end = offset + logfmt::kEventHeaderSize + static_cast<uint64_t>(h.channel_len) + static_cast<uint64_t>(h.data_len);
  if (h.end > size) return std::nullopt;
  return h;
}

std::optional<uint64_t> EventScanner::find_event(uint64_t from, uint64_t limit) const {
  const uint64_t size = bytes_.size();
  while (from < limit && limit <= size && limit - from >= 4) {
    const void* hit = memmem(bytes_.data() + from, limit - from, kSyncBytes, 4);
    if (hit == nullptr) return std::nullopt;
    const uint64_t at = static_cast<const uint8_t*>(hit) - bytes_.data();
    if (plausible_event_at(at)) return at;
    from = at + 1;
  }
  return std::nullopt;
}

std::optional<uint64_t> EventScanner::find_chained_event(uint64_t from, uint64_t limit) const {
  while (auto at = find_event(from, limit)) {
    const auto h = plausible_event_at(*at);
    if (h->end == bytes_.size() || sync_at(h->end)) return at;
    from = *at + 1;
  }
  return std::nullopt;
}

std::optional<uint64_t> EventScanner::resync(uint64_t from) const {
  const auto at = find_event(from, bytes_.size());
  if (!at) return at;
  // A sync word in garbage can start a plausible-looking event that overlaps the real next one;
  // prefer an event inside it that chains to the one after.
  const auto h = plausible_event_at(*at);
  if (h->end == bytes_.size() || sync_at(h->end)) return at;
  if (const auto chained = find_chained_event(*at + 1, h->end)) return chained;
  return at;
}

void EventScanner::report(uint64_t offset, ProblemKind kind, std::string detail) {
  ++problems_;
  if (on_problem_ != nullptr && *on_problem_) (*on_problem_)(Problem{offset, kind, std::move(detail)});
}

bool EventScanner::next(Event& out) {
  const uint64_t size = bytes_.size();
  if (size == 0) {
    if (!empty_reported_) report(0, ProblemKind::kEmptyFile, "the file is empty (0 bytes)");
    empty_reported_ = true;
    return false;
  }
  while (pos_ < size && pos_ < limit_) {
    if (size - pos_ < 4 && std::memcmp(bytes_.data() + pos_, kSyncBytes, size - pos_) == 0) {
      report(pos_, ProblemKind::kTruncatedEvent,
             "last event cut off by the end of the file after " + std::to_string(size - pos_) + " of 28 header bytes");
      pos_ = size;
      return false;
    }
    if (!sync_at(pos_)) {
      const auto next = resync(pos_ + 1);
      report(pos_, ProblemKind::kGarbage,
             "no sync word where an event should start" + skipped(pos_, next, size));
      pos_ = next.value_or(size);
      continue;
    }
    if (size - pos_ < logfmt::kEventHeaderSize) {
      report(pos_, ProblemKind::kTruncatedEvent,
             "last event cut off by the end of the file after " + std::to_string(size - pos_) + " of 28 header bytes");
      pos_ = size;
      return false;
    }
    const uint8_t* p = bytes_.data() + pos_;
    const auto channel_len = static_cast<int32_t>(logfmt::load_be32(p + 20));
    const auto data_len = static_cast<int32_t>(logfmt::load_be32(p + 24));
    if (channel_len <= 0 || channel_len > logfmt::kMaxChannelLength) {
      const auto next = resync(pos_ + 1);
      report(pos_, ProblemKind::kBadChannelLength,
             "channel length " + std::to_string(channel_len) + " is outside 1.." +
                 std::to_string(logfmt::kMaxChannelLength) + skipped(pos_, next, size));
      pos_ = next.value_or(size);
      continue;
    }
    if (data_len < 0) {
      const auto next = resync(pos_ + 1);
      report(pos_, ProblemKind::kBadLength, "negative data length " + std::to_string(data_len) + skipped(pos_, next, size));
      pos_ = next.value_or(size);
      continue;
    }
    const uint64_t end = pos_ + logfmt::kEventHeaderSize + static_cast<uint64_t>(channel_len) +
                         static_cast<uint64_t>(data_len);
    if (end > size) {
      const auto next = resync(pos_ + 1);
      if (!next) {
        report(pos_, ProblemKind::kTruncatedEvent,
               "last event cut off: it needs " + std::to_string(end - pos_) + " bytes but the file ends after " +
                   std::to_string(size - pos_));
        pos_ = size;
        return false;
      }
      report(pos_, ProblemKind::kBadLength,
             "data length " + std::to_string(data_len) + " points past the end of the file" + skipped(pos_, next, size));
      pos_ = *next;
      continue;
    }
    if (end != size && !sync_at(end)) {
      // Either garbage follows this event, or its length is corrupt and overruns the next event.
      if (const auto next = find_chained_event(pos_ + 1, end)) {
        report(pos_, ProblemKind::kBadLength,
               "data length " + std::to_string(data_len) + " overruns the next event" + skipped(pos_, next, size));
        pos_ = *next;
        continue;
      }
    }
    out.event_number = static_cast<int64_t>(logfmt::load_be64(p + 4));
    out.utime = static_cast<int64_t>(logfmt::load_be64(p + 12));
    out.channel = std::string_view(reinterpret_cast<const char*>(p + logfmt::kEventHeaderSize),
                                   static_cast<size_t>(channel_len));
    out.data = bytes_.subspan(pos_ + logfmt::kEventHeaderSize + channel_len, static_cast<size_t>(data_len));
    out.offset = pos_;
    pos_ = end;
    return true;
  }
  return false;
}

}  // namespace internal
}  // namespace driftlab
