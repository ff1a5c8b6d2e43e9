// Events and problems met while reading an LCM event log.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>

namespace driftlab {

/// One event of a log. channel and data point into the reader's mapping of the file and stay valid
/// for the lifetime of the reader (zero copy).
struct Event {
  int64_t event_number = 0;  ///< as written by the logger (lcm-logger counts from 0)
  int64_t utime = 0;         ///< log timestamp: receive time at the recorder [microseconds]
  std::string_view channel;
  std::span<const uint8_t> data;
  uint64_t offset = 0;       ///< byte offset of the event's sync word in the file
};

enum class ProblemKind {
  kEmptyFile,          ///< the file has no bytes
  kGarbage,            ///< bytes between events that are not an event
  kTruncatedEvent,     ///< the last event is cut off by the end of the file
  kBadLength,          ///< a data length that is negative, points past the end, or overruns the next event
  kBadChannelLength,   ///< a channel length of 0 or more than logfmt::kMaxChannelLength
};

/// "empty_file", "garbage", "truncated_event", "bad_length" or "bad_channel_length".
const char* to_string(ProblemKind kind);

/// A problem found in a log, with the byte offset where it starts and a one-line explanation.
struct Problem {
  uint64_t offset = 0;
  ProblemKind kind = ProblemKind::kGarbage;
  std::string detail;
};

/// Called for each problem as it is met while streaming; reading then resumes at the next event.
using ProblemCallback = std::function<void(const Problem&)>;

}  // namespace driftlab
