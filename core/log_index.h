// LogIndex: one pass over a log that yields its summary (channels, problems) and a sparse time index for
// seeking. Cached beside the log as LOG.dlidx and rebuilt when the log changed.
// Thread-safety: a built index is immutable and may be shared between threads.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/log_event.h"
#include "core/result.h"

namespace driftlab {

struct ChannelSummary {
  std::string name;
  int64_t count = 0;        ///< events [count]
  int64_t bytes = 0;        ///< payload bytes [bytes]
  int64_t first_utime = 0;  ///< log timestamp of the first event [us]
  int64_t last_utime = 0;   ///< log timestamp of the last event [us]
  int64_t fingerprint = 0;  ///< LCM fingerprint of the first message (0 when shorter than 8 bytes)
  bool mixed_fingerprints = false;  ///< later messages carry another fingerprint
  int64_t times_back = 0;   ///< events whose log timestamp is older than the channel's event before [count]
  /// Counted when the index was built with a HeaderReader (LogSummary::stamps_counted), else 0:
  int64_t stamped = 0;          ///< messages that carry a stream header [count]
  int64_t stamps_repeated = 0;  ///< of those, stamped exactly as the one before with another seq [count]
};

/// A message's stream header as the index counts it: its seq and stamp [us].
struct HeaderFields {
  int64_t seq = 0;
  int64_t utime = 0;
};
/// Reads a message's stream header, nullopt when its type carries none. Core knows no message types: who wants the
/// stamp counts gives this (analyzers/log_info.h gives lcmtypes/stream_header.h's read_header).
using HeaderReader = std::function<std::optional<HeaderFields>(std::span<const uint8_t> data, int64_t utime)>;

struct LogSummary {
  uint64_t file_bytes = 0;
  int64_t events = 0;       ///< intact events [count]
  int64_t start_utime = 0;  ///< smallest event timestamp [us] (0 without events)
  int64_t end_utime = 0;    ///< largest event timestamp [us]
  std::vector<ChannelSummary> channels;  ///< sorted by name
  std::vector<Problem> problems;         ///< the first kMaxStoredProblems problems, in file order
  uint64_t problems_total = 0;           ///< all problems, including those not stored
  bool stamps_counted = false;           ///< the channels' stamped and stamps_repeated were counted
};

class LogIndex {
 public:
  static constexpr size_t kMaxStoredProblems = 1000;
  /// An index entry every this many bytes of log.
  static constexpr uint64_t kBlockBytes = 1ull << 20;

  struct Entry {
    uint64_t offset;      ///< an event's offset
    int64_t utime;        ///< its timestamp [us]
    int64_t prefix_max;   ///< largest timestamp of all events before it [us]
  };

  /// Logs smaller than this are scanned every time rather than cached (scanning them is instant).
  static constexpr uint64_t kDefaultCacheMinBytes = 16ull << 20;

  /// Loads LOG.dlidx when it matches the log (size, mtime, inode, content sample) and, when `headers` is given,
  /// holds the stamp counts; else scans the log and, for logs of at least cache_min_bytes that hold events, writes
  /// the cache (silently skipped when the folder is read-only), so an index built to seek is scanned again once
  /// for the counts. on_progress(done, total) [bytes] is called while scanning. Errors name the log file.
  static Result<LogIndex> load_or_build(const std::string& log_path,
                                        const std::function<void(uint64_t, uint64_t)>& on_progress = {},
                                        uint64_t cache_min_bytes = kDefaultCacheMinBytes,
                                        const HeaderReader& headers = {});
  /// Scans bytes in one pass, counting stamps with `headers` when given. on_progress, if given, is called with the
  /// offset reached about every kBlockBytes.
  static LogIndex build(std::span<const uint8_t> bytes, const std::function<void(uint64_t)>& on_progress = {},
                        const HeaderReader& headers = {});
  static std::string cache_path(const std::string& log_path) { return log_path + ".dlidx"; }

  const LogSummary& summary() const { return summary_; }
  const std::vector<Entry>& entries() const { return entries_; }
  bool from_cache() const { return from_cache_; }

  /// Offset from which a forward scan finds the first event (in file order) whose timestamp is >= utime.
  uint64_t seek_offset(int64_t utime) const;

 private:
  LogSummary summary_;
  std::vector<Entry> entries_;
  bool from_cache_ = false;
};

}  // namespace driftlab
