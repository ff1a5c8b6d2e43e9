// LogReader: a streaming, zero-copy reader for LCM event logs.
// Memory stays constant on logs of any size (the file is mapped and pages behind the cursor are released).
// Corruption never stops it: each problem goes to the problem callback with its byte offset and reading
// resumes at the next event. Thread-safety: one reader per thread; events stay valid while the reader lives.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/log_event.h"
#include "core/result.h"

namespace driftlab {

struct ReadOptions {
  /// Only channels fully matching this ECMAScript regex (as lcm-logger's -c); empty: every channel.
  std::string channels;
  /// Channels read whatever `channels` says: the bookkeeping that tells how to read the others (an import's
  /// CHANNEL_SOURCES and FOREIGN_SCHEMAS).
  std::vector<std::string> also;
  /// Called for every problem met while streaming (may be empty).
  ProblemCallback on_problem;
};

class LogReader {
 public:
  /// Opens a log file. Errors (missing file, a directory, a bad regex) name the file or the regex.
  static Result<LogReader> open(const std::string& path, ReadOptions options = {});
  /// Reads a log held in memory (bytes must outlive the reader). Seeking builds an in-memory index.
  static Result<LogReader> from_memory(std::span<const uint8_t> bytes, ReadOptions options = {});

  LogReader(LogReader&&) noexcept;
  LogReader& operator=(LogReader&&) noexcept;
  ~LogReader();

  /// The next intact event whose channel matches; false at the end of the log.
  bool next(Event& out);

  /// Positions the reader on the first event (in file order) whose timestamp is >= utime [us], using the
  /// index (loaded from LOG.dlidx, or built in one pass and cached).
  Status seek(int64_t utime);
  /// Back to the first event.
  void rewind();

  /// For readers that split a log between threads, each reading its byte range: where an event seems to start at
  /// or after offset (nullopt: none does); reading [begin, end) of the file: from the event at begin (the start
  /// of an event), up to the last event that starts before end. After the range, position() is end exactly when
  /// the range's last event ended there, as a reader from the start would have found it.
  std::optional<uint64_t> event_at_or_after(uint64_t offset) const;
  void read_range(uint64_t begin, uint64_t end);

  const std::string& path() const;
  uint64_t size_bytes() const;
  /// Byte offset where the next event is looked for.
  uint64_t position() const;
  /// Problems met so far.
  uint64_t problems() const;

 private:
  struct Impl;
  explicit LogReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Whether the file at path is an LCM event log with at least one intact event, for commands that have nothing to
/// do without one. Errors, one line naming the file: those of LogReader::open (missing, a directory, a FIFO),
/// "empty file (0 bytes): no events", not_an_event_log() for a file that neither starts with an event nor holds
/// one, and "no intact event in N bytes" for a log damaged throughout. Reads up to the first intact event (the
/// whole file only when it has none).
Status check_event_log(const std::string& path);

/// "PATH: not an LCM event log (no event in N bytes; an event starts with the sync word 0xEDA1DA01)".
std::string not_an_event_log(const std::string& path, uint64_t bytes);

}  // namespace driftlab
