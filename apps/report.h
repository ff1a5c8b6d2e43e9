// `driftlab report`: the HTML page with plots, also made by `driftlab demo`.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::apps {

struct ReportOptions {
  std::vector<std::string> logs;   ///< the recording first, then replays of it
  std::string out;                 ///< folder for index.html, the PNGs and report.json
  std::string diagnosis;           ///< `driftlab diagnose --json` of the first log; empty: diagnose it here
  std::vector<std::string> evals;  ///< `driftlab eval --json` files to tabulate
  std::string gt_channel = "GROUND_TRUTH";
  std::string title;
  /// Told what the report does next ("reading run.lcm", "diagnosing run.lcm", "drawing the plots"), for a progress
  /// line.
  std::function<void(const std::string&)> on_stage;
};

/// Writes the report; returns the page's path. Errors name the file or option at fault; a failure of the plotting
/// script (python3 with matplotlib) is reported with its exit code.
Result<std::string> make_report(const ReportOptions& options);

}  // namespace driftlab::apps
