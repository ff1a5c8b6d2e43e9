// The data `driftlab report` plots (its report.json), from the logs it reads and the diagnosis of the first: each
// stream's arrivals, latency, spikes and drop gaps; the reference trajectory and every estimate aligned onto it
// with its error over time (or, without a reference, the poses aligned onto the longest); an arm's commanded
// against measured joint motion with the delay diagnose measured; what each estimator fused and rejected; the
// maps. analyzers/report_page.py draws the page from it. Thread-safety: pure functions.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "analyzers/log_series.h"
#include "core/result.h"

namespace driftlab::analyzers {

struct ReportInputs {
  std::vector<LogSeries> logs;                     ///< the recording first, then replays of it; not empty
  std::vector<std::string> names;                  ///< each log as given (a bag's own name, not its conversion's)
  nlohmann::json diagnosis;                        ///< the first log's, as `driftlab diagnose --json` prints it
  nlohmann::json evals = nlohmann::json::array();  ///< `driftlab eval --json` results: [{"file", "result"}]
  std::string gt_channel = "GROUND_TRUTH";
  std::string title;  ///< empty: from the first log's name
};

/// The page's data. Maps are listed by their file in the report folder (map_file), which the caller writes. An
/// error says how the diagnosis is not `driftlab diagnose --json`'s.
Result<nlohmann::json> report_data(const ReportInputs& in);

/// The file of a log's map in the report folder: "map-LOGSTEM-CHANNEL.png".
std::string map_file(const LogSeries& log, const MapImage& map);

}  // namespace driftlab::analyzers
