// `driftlab report`'s page, also drawn by `driftlab demo`: the logs read (another tool's recording through its
// conversion, a PX4 flight log beside a bag on the bag's clock), the first diagnosed unless a diagnosis is given,
// the data the page plots (analyzers/report_data.h) written to DIR/report.json, and matplotlib drawing it
// (analyzers/report_page.py, compiled into the library), since a maintained plotting library draws better plots
// than we would by hand.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::report {

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

}  // namespace driftlab::report
