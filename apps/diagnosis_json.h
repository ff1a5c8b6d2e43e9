// The JSON form of a timing diagnosis (docs/diagnosis.md lists its fields).
#pragma once

#include <nlohmann/json.hpp>

#include "analyzers/flight_log.h"
#include "analyzers/timing.h"
#include "core/config.h"
#include "core/result.h"

namespace driftlab::apps {

/// The ranges of diagnose's --max-lag and --window [s].
inline constexpr config::Range kMaxLagRange = config::above(0, 10);
inline constexpr config::Range kWindowRange = config::above(0, 86400);

/// `driftlab diagnose` on an LCM log: the timing diagnosis and, for a PX4 flight log, the flight controller's own
/// account (`flight.present`). The command and the Python module (python/) both run it.
struct DiagnoseRun {
  analyzers::Diagnosis diagnosis;
  analyzers::FlightLogDiagnosis flight;
};
/// Errors: one line naming the log.
Result<DiagnoseRun> run_diagnosis(const std::string& log, const analyzers::DiagnoseOptions& options);
/// What `driftlab diagnose --json` prints for a run.
nlohmann::json diagnose_json(const DiagnoseRun& run);

/// What `driftlab diagnose --json` prints: times in seconds unless the key says utime [us].
nlohmann::json to_json(const analyzers::Diagnosis& d);

/// The flight-log diagnosis (analyzers/flight_log.h) as `diagnose --json` prints it under "flight_log": times in
/// seconds from the log's start.
nlohmann::json flight_log_json(const analyzers::FlightLogDiagnosis& f);

/// A flight's UTC (analyzers/flight_log.h) as `info --json` and `diagnose --json` print it under "utc": null when
/// the log has no GNSS time.
nlohmann::json flight_utc_json(const analyzers::FlightUtc& u);
/// Its line in `info`'s and `diagnose`'s text; empty when the log has no GNSS time.
std::string flight_utc_line(const analyzers::FlightUtc& u);

/// The flight-log section of `driftlab diagnose`'s text, a line each (empty when the log has no ULog data).
std::vector<std::string> flight_log_lines(const analyzers::FlightLogDiagnosis& f);

/// The headline of a diagnosis (as to_json gives it), shared by the report page and the demo's summary:
/// `worst_stream` ({name, verdict, reasons, causes}, or null when nothing was flagged: faults before warnings, among
/// them the deepest first cause: a clock, then a late stream or loop, loss, undecodable data, a symptom; then the
/// most reasons), `clocks_ahead_s` (channel -> offset,
/// clocks ahead by 1 ms or more; one behind cannot be told from latency in one log) and `drops` (channel -> count).
/// Throws nlohmann::json::exception when the JSON is not a diagnosis.
nlohmann::json diagnosis_summary(const nlohmann::json& diagnosis);

}  // namespace driftlab::apps
