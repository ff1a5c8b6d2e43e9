// driftlab report LOG... --out DIR: the command line of report/report.h's page.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "reporting/report.h"

namespace driftlab::apps {

void add_report_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<report::ReportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Write one self-contained HTML page with plots (and a PNG of each) of what the logs say.");
  cmd->footer(
      "The first LOG is the recording (a simulator or recorder log); later logs are replays of it, whose new pose\n"
      "channels are shown as estimates. A PX4 flight log (.ulg) given with a bag of the same flight is one\n"
      "recording, the flight log put on the bag's clock as `driftlab diagnose BAG FLIGHT.ulg` does. Plots:\n"
      "trajectories in the plane (estimates aligned in position and yaw); error over time with drops, gaps and\n"
      "latency spikes on the same axis; latency over time and histograms; inter-arrival times; skew correlation\n"
      "curves; SLAM maps; an arm's commanded and measured joint motion with the delay diagnose measures between\n"
      "them; a PX4 flight log's timeline (the logger's dropouts, sensor gaps, the estimator's rejections and\n"
      "timeouts on one axis). The time plots zoom in the page (dygraphs, from libjs-dygraphs, inlined: it opens\n"
      "offline; without it the page keeps the PNGs). Without --diagnosis the first log is diagnosed. Needs python3\n"
      "with matplotlib. DIR gets index.html, a PNG per plot and report.json (the data plotted).");
  cmd->add_option("logs", o->logs, "Logs: the recording first, then replays of it")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--out", o->out, "Folder to write the report into")->required();
  cmd->add_option("--diagnosis", o->diagnosis, "Diagnosis of the first log (driftlab diagnose --json)");
  cmd->add_option("--eval", o->evals, "Trajectory or arm evaluation to tabulate (driftlab eval --json; repeatable)");
  cmd->add_option("--gt", o->gt_channel, "Ground-truth channel")->capture_default_str();
  cmd->add_option("--title", o->title, "Page title (default: from the first log)");
  cmd->callback([o, exit_code] {
    std::vector<std::string> inputs = o->logs;
    inputs.push_back(o->diagnosis);
    inputs.insert(inputs.end(), o->evals.begin(), o->evals.end());
    if (Status s = refuse_same_file(o->out, inputs, "-o", OutputKind::kFolder); !s) {
      *exit_code = fail(s.message());
      return;
    }
    StageLine line("report");
    report::ReportOptions options = *o;
    options.on_stage = [&line](const std::string& what) { line.set("report: " + what); };
    auto page = report::make_report(options);
    line.finish();
    if (!page) {
      *exit_code = fail(page.error().message, exit_code_for(page.error()));
      return;
    }
    std::printf("%s\n", page->c_str());
    *exit_code = kExitOk;
  });
}

}  // namespace driftlab::apps
