// The JSON form of a timing diagnosis (docs/diagnosis.md lists its fields): what `driftlab diagnose --json` prints,
// and what `driftlab report`, `driftlab demo`, the batches (batch/) and the Python module read.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "analyzers/flight_log.h"
#include "analyzers/timing.h"
#include "core/result.h"

namespace driftlab::analyzers {

/// `driftlab diagnose` on an LCM log: the timing diagnosis and, for a PX4 flight log, the flight controller's own
/// account (`flight.present`). The command and the Python module (python/) both run it.
struct DiagnoseRun {
  Diagnosis diagnosis;
  FlightLogDiagnosis flight;
};
/// Errors: one line naming the log.
Result<DiagnoseRun> run_diagnosis(const std::string& log, const DiagnoseOptions& options);
/// What `driftlab diagnose --json` prints for a run.
nlohmann::json diagnose_json(const DiagnoseRun& run);

/// What `driftlab diagnose --json` prints: times in seconds unless the key says utime [us].
nlohmann::json to_json(const Diagnosis& d);

/// The flight-log diagnosis (analyzers/flight_log.h) as `diagnose --json` prints it under "flight_log": times in
/// seconds from the log's start.
nlohmann::json flight_log_json(const FlightLogDiagnosis& f);

/// A flight's UTC (analyzers/flight_log.h) as `info --json` and `diagnose --json` print it under "utc": null when
/// the log has no GNSS time.
nlohmann::json flight_utc_json(const FlightUtc& u);

/// The headline of a diagnosis (as to_json gives it), shared by the report page, the demo's summary and the
/// batches' tables: `worst_stream` ({name, verdict, reasons, causes}, or null when nothing was flagged: faults
/// before warnings, among them the deepest first cause: a clock, then a late stream or loop, loss, undecodable data,
/// a symptom; then the most reasons), `clocks_ahead_s` (channel -> offset, clocks ahead by 1 ms or more; one behind
/// cannot be told from latency in one log) and `drops` (channel -> count).
/// Throws nlohmann::json::exception when the JSON is not a diagnosis.
nlohmann::json diagnosis_summary(const nlohmann::json& diagnosis);

}  // namespace driftlab::analyzers
