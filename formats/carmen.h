// CARMEN logs (.log, .clf; plain or gzip): the text logs of the CARMEN robot toolkit, in which the public 2D
// laser datasets (Intel, ACES, FR079, MIT) ship. Each line becomes a driftlab message on a channel named after
// its CARMEN message (FLASER, RLASER, RAWLASER1..4, ROBOTLASER1..2, ODOM, TRUEPOS), stamped with its
// ipc_timestamp (the source clock) and logged at its logger_timestamp (the arrival). Thread-safety: one reader
// per thread.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/mapped_file.h"
#include "core/result.h"

namespace driftlab::formats {

struct CarmenMessage {
  std::string_view channel;
  const char* type = "";  ///< driftlab type name
  int64_t log_utime = 0;  ///< logger_timestamp [us]
  std::vector<uint8_t> lcm;
  size_t line = 0;
};

class CarmenReader {
 public:
  /// Maps path; a gzip log (.clf.gz) is inflated as it is read, a line at a time, never whole: its lines may be
  /// 16 MiB each at most, and it may inflate to DecodeBudget's bound (1 GiB and 256 times its size); past either,
  /// reading stops with one problem naming the line.
  static Result<CarmenReader> open(const std::string& path);
  /// A log's text in memory: for fuzzing and tests. No check that it looks like CARMEN.
  static CarmenReader from_text(std::string text) {
    CarmenReader r;
    r.text_ = std::move(text);
    return r;
  }
  /// Whether these (decompressed) first bytes look like a CARMEN log.
  static bool looks_like(std::string_view head);

  /// Calls on_message for each message in line order and on_problem(line, what) for each line that does not
  /// parse; returns the number of messages. Lines CARMEN tools write that carry no data driftlab has a type for
  /// (SYNC, NEFF, comments) are counted in skipped().
  int64_t read(const std::function<void(const CarmenMessage&)>& on_message,
               const std::function<void(size_t line, const std::string& what)>& on_problem);

  /// Lines skipped by CARMEN message name.
  const std::vector<std::pair<std::string, int64_t>>& skipped() const { return skipped_; }

 private:
  CarmenReader() = default;
  /// Calls fn(line number, line) for each line; returns "" or why reading stopped, with the line it stopped at.
  std::string each_line(const std::function<void(size_t, std::string_view)>& fn, size_t* stopped_at) const;
  std::string text_;  // from_text's
  MappedFile file_;   // open()'s
  bool gzip_ = false;
  std::vector<std::pair<std::string, int64_t>> skipped_;
};

}  // namespace driftlab::formats
