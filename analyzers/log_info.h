// What a log holds, as `driftlab info` says it: its channels (type, the type in the recording it was imported from,
// count, bytes, rate, time range), what its index saw wrong in time and in framing, the statistics a driftlab
// recorder left in it, and a PX4 flight's time of day. Thread-safety: functions on files.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "analyzers/flight_log.h"
#include "core/log_index.h"
#include "core/result.h"
#include "driftlab/recorder_stats_t.hpp"

namespace driftlab::analyzers {

struct LogInfo {
  std::string path;
  LogSummary summary;
  /// Each channel's type in the recording it was imported from (channel -> "sensor_msgs/msg/Imu"), from what the
  /// import wrote on CHANNEL_SOURCES; empty for a log driftlab recorded.
  std::map<std::string, std::string, std::less<>> source_types;
  /// The last statistics a driftlab recorder wrote into the log (they are cumulative), if it has any.
  std::optional<driftlab::recorder_stats_t> recorder;
  FlightUtc utc;  ///< a PX4 flight's time of day, from its GNSS receiver (ULOG_UTC)
};

/// Indexes the log (once: the index is kept beside it; `progress` is called as it is read). Errors name the file:
/// unreadable, or not an event log at all.
Result<LogInfo> log_info(const std::string& path, const std::function<void(uint64_t, uint64_t)>& progress = {});

/// What `driftlab info --json` prints.
nlohmann::json to_json(const LogInfo& info);

/// What `driftlab info` prints: the summary and channel table, the timing and framing problems (up to
/// max_problems of the latter listed), the flight's UTC and the recorder's statistics.
std::string log_info_text(const LogInfo& info, int max_problems);

}  // namespace driftlab::analyzers
