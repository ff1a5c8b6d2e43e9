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
  /// Reads path whole (a log is text of tens of MB at most), gunzipping it when it is gzip.
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
  std::string text_;
  std::vector<std::pair<std::string, int64_t>> skipped_;
};

}  // namespace driftlab::formats
