// driftlab diagnose LOG: which stream is late, lossy or on the wrong clock, from the log alone.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <memory>

#include "analyzers/diagnosis_json.h"
#include "analyzers/diagnosis_text.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/diagnose_ranges.h"
#include "core/same_file.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

using analyzers::Diagnosis;

struct DiagnoseOptions {
  std::vector<std::string> inputs;
  std::string log;
  JsonOutput json;
  std::string html;
  std::string fail_on;  ///< "", "warn" or "fault"
  analyzers::DiagnoseOptions analysis;
};

/// Exit code of `diagnose --fail-on`: a stream's verdict at that level or worse (for "warn", also a problem of the
/// log as a whole: a TF chain, a flight log's dropouts) makes the command fail, for CI.
inline constexpr int kExitProblemsFound = 3;

/// Whether `--fail-on LEVEL` fails for what a diagnosis found.
bool fails(analyzers::Severity worst, const std::string& level) {
  if (level.empty()) return false;
  return worst >= (level == "fault" ? analyzers::Severity::kFault : analyzers::Severity::kWarn);
}

int run_diagnose(const DiagnoseOptions& o) {
  if (Status s = o.json.check({o.log}, {o.html}); !s) return fail(s.message());
  if (Status s = refuse_same_file(o.html, {o.log}, "--html"); !s) return fail(s.message());
  auto run = analyzers::run_diagnosis(o.log, o.analysis);
  if (!run) return fail(run.error().message);
  const Diagnosis& d = run->diagnosis;
  const analyzers::DiagnosisText text = analyzers::diagnosis_text(*run);
  const bool failing = fails(analyzers::worst_severity(d, text), o.fail_on);
  if (!o.html.empty() && !write_output(o.html, analyzers::diagnosis_html(d, text))) return kExitFailure;
  if (o.json.wanted()) {
    if (!o.json.emit(analyzers::diagnose_json(*run).dump(2) + "\n")) return kExitFailure;
    if (o.json.print) return failing ? kExitProblemsFound : kExitOk;
  }
  std::fputs(analyzers::to_text(text).c_str(), stdout);
  return failing ? kExitProblemsFound : kExitOk;
}

}  // namespace

void add_diagnose_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<DiagnoseOptions>();
  CLI::App* cmd = app.add_subcommand(
      "diagnose",
      "Find skew, clock offset and drift, latency, drops, duplicates and reordering in a log; in a PX4 flight log, "
      "the logger's dropouts, the IMU's timing and the estimator's health too.");
  cmd->add_option("log", o->inputs, kLogInputHelp)->required();
  add_json_options(cmd, &o->json, "the diagnosis");
  cmd->add_option("--html", o->html, "Also write the report as an HTML page");
  cmd->add_option("-c,--channels", o->analysis.channels,
                  "Only channels fully matching this regex (ECMAScript), as export csv's -c");
  cmd->add_option("--fail-on", o->fail_on,
                  "Exit with 3 when a stream is at this verdict or worse (warn: also any problem listed), for CI")
      ->check(CLI::IsMember({"warn", "fault"}));
  cmd->add_option("--max-lag", o->analysis.max_lag_s, "Skew search range [s]")
      ->capture_default_str()
      ->check(in_range(kMaxLagRange, "s"));
  cmd->add_option("--window", o->analysis.window_s, "Skew window [s]")
      ->capture_default_str()
      ->check(in_range(kWindowRange, "s"));
  cmd->callback([o, exit_code] {
    // The recording given, not only its conversion; --json-out nor --html where the other goes.
    Status checked = o->json.check(o->inputs, {o->html});
    if (checked) checked = refuse_same_file(o->html, o->inputs, "--html");
    if (!checked) {
      *exit_code = fail(checked.message());
      return;
    }
    auto log = recordings::event_log_for(o->inputs);
    if (!log) {
      *exit_code = fail(log.error().message, exit_code_for(log.error()));
      return;
    }
    o->log = *log;
    *exit_code = run_diagnose(*o);
  });
}

}  // namespace driftlab::apps
