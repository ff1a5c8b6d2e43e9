// `driftlab diagnose`'s text: a row per channel, the stream pairs, the TF tree, command loops and a PX4 flight log's
// section, with the problems in words; its HTML page; the worst verdict `--fail-on` judges by; and the flight log's
// UTC line `driftlab info` prints too. The text form of what diagnosis_json.h gives as JSON.
// Thread-safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "analyzers/diagnosis_json.h"
#include "analyzers/flight_log.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers {

struct DiagnosisText {
  std::vector<std::string> lines;     ///< the report, a line each
  std::vector<std::string> problems;  ///< in words, a flight log's first (a logger dropout explains the gaps after it)
};

/// The text of a diagnosis, as `driftlab diagnose` prints it.
DiagnosisText diagnosis_text(const DiagnoseRun& run);

/// The text as `driftlab diagnose` prints it: the lines, then the problems (up to 10, the rest counted) or that
/// none was found.
std::string to_text(const DiagnosisText& text);

/// The text as one HTML page (`driftlab diagnose --html`).
std::string diagnosis_html(const Diagnosis& d, const DiagnosisText& text);

/// The worst a diagnosis found: kFault when a stream's verdict is fault; kWarn when one is warn, or the text lists
/// a problem of the log as a whole (a TF chain, a flight log's dropouts); kOk otherwise.
Severity worst_severity(const Diagnosis& d, const DiagnosisText& text);

/// A flight's UTC line in `info`'s and `diagnose`'s text; empty when the log has no GNSS time.
std::string flight_utc_line(const FlightUtc& u);

/// The flight-log section of `driftlab diagnose`'s text, a line each (empty when the log has no ULog data).
std::vector<std::string> flight_log_lines(const FlightLogDiagnosis& f);

}  // namespace driftlab::analyzers
