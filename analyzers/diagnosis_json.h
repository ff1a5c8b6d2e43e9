// The JSON form of a timing diagnosis (docs/diagnosis.md lists its fields): what `driftlab diagnose --json` prints,
// and what `driftlab report`, `driftlab demo`, the batches (batch/) and the Python module read.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

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

/// A stream's verdict, or the worst of a log: ok, warn, fault.
enum class Severity { kOk, kWarn, kFault };
/// "ok", "warn", "fault"; severity_from_name is kOk for any other word.
const char* severity_name(Severity s);
Severity severity_from_name(std::string_view name);

/// The headline of a diagnosis, shared by the report page, the demo's summary and the batches' tables.
struct DiagnosisSummary {
  struct Stream {
    std::string name;
    Severity verdict = Severity::kOk;
    std::vector<std::string> reasons, causes;
  };
  /// Faults before warnings, among them the deepest first cause (a clock, then a late stream or loop, loss,
  /// undecodable data, a symptom), then the most reasons; none when nothing was flagged.
  std::optional<Stream> worst_stream;
  std::vector<Stream> streams;  ///< every channel diagnosed, in the diagnosis's order
  /// Clocks ahead by 1 ms or more (one behind cannot be told from latency in one log), not those of a clock of
  /// another epoch (simulation time), whose offset is against its peers.
  std::map<std::string, double> clocks_ahead_s;
  std::map<std::string, int64_t> drops;  ///< channel -> packets missing, when any are
  int fault_streams = 0, warn_streams = 0;
};
/// The summary of a diagnosis as to_json gives it (what `diagnose --json-out` wrote). Errors: one line when the
/// JSON is not a diagnosis.
Result<DiagnosisSummary> summarize(const nlohmann::json& diagnosis);
/// The summary as the report page and the demo's --json give it: `worst_stream` ({name, verdict, reasons,
/// causes}, or null), `clocks_ahead_s`, `drops`.
nlohmann::json to_json(const DiagnosisSummary& s);

}  // namespace driftlab::analyzers
