// The text of `driftlab diagnose` and `driftlab info` for a PX4 flight log, and diagnose's option ranges (the
// command and the Python module check them alike).
#pragma once

#include <string>
#include <vector>

#include "analyzers/flight_log.h"
#include "core/config.h"

namespace driftlab::apps {

/// The ranges of diagnose's --max-lag and --window [s].
inline constexpr config::Range kMaxLagRange = config::above(0, 10);
inline constexpr config::Range kWindowRange = config::above(0, 86400);

/// A flight's UTC line in `info`'s and `diagnose`'s text; empty when the log has no GNSS time.
std::string flight_utc_line(const analyzers::FlightUtc& u);

/// The flight-log section of `driftlab diagnose`'s text, a line each (empty when the log has no ULog data).
std::vector<std::string> flight_log_lines(const analyzers::FlightLogDiagnosis& f);

}  // namespace driftlab::apps
