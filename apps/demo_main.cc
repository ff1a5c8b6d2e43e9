// driftlab demo: the first thing a new user runs. Simulates the default scenario with its faults, diagnoses the
// log, replays it through SLAM, the estimator and the controller as logged and again with the clocks the
// diagnosis found corrected, scores both estimates against ground truth and writes the report. Each stage is this
// program run again with the stage's subcommand (as `git` runs its own), its JSON kept in the output folder, so
// every number the demo prints can be reproduced with the command it shows.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <memory>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "batch/demo.h"
#include "core/progress_line.h"
#include "core/wall_clock.h"
#include "reporting/report.h"

namespace driftlab::apps {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  batch::DemoSettings settings;  ///< out: default logs/demo, or logs/demo-drone with --drone (never over another's)
  JsonOutput json;
};

/// "[3/7] replaying the log".
std::string stage_label(int index, int total, const std::string& what) {
  return "[" + std::to_string(index) + "/" + std::to_string(total) + "] " + what;
}

int run_demo(const batch::DemoSettings& a, const JsonOutput& json) {
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) return fail(a.out + ": cannot create the demo folder: " + ec.message());
  auto plan = batch::plan_demo(a, self_path());
  if (!plan) return fail("demo: " + plan.error().message, kExitFailure);
  // Each stage printed as its command line (unless --json), with a progress line while it runs; the report is
  // drawn in-process as the last.
  const int total = static_cast<int>(plan->stages.size()) + 1;
  auto announce = [&json](const std::vector<std::string>& args) {
    if (!json.print) std::printf("== %s\n", batch::command_text(args).c_str());
    std::fflush(stdout);
  };
  std::vector<batch::StageRun> stages =
      batch::run_stages(*plan, a.out, [&](size_t i, const std::function<void()>& run) {
        announce(plan->stages[i].args);
        const StageLine line(stage_label(static_cast<int>(i) + 1, total, plan->stages[i].what));
        run();
      });
  if (const batch::StageRun& last = stages.back(); last.code != 0) {
    // The demo's exit code: 2 when the stage was given bad input, 1 otherwise.
    return fail("demo: " + batch::command_text(plan->stages[stages.size() - 1].args) + " failed (exit " +
                    std::to_string(last.code) + ")" + (last.said.empty() ? "" : ": " + last.said),
                last.code == kExitBadInput ? kExitBadInput : kExitFailure);
  }
  announce(plan->report_command);
  const report::ReportOptions r{.logs = plan->report_logs,
                                .out = plan->report_dir,
                                .diagnosis = plan->diagnosis,
                                .evals = plan->evals,
                                .title = plan->title};
  const Stopwatch drawing;
  Result<std::string> page = Error{""};
  {
    const StageLine line(stage_label(total, total, "drawing the report"));
    page = report::make_report(r);
  }
  if (!page) return fail("demo: " + page.error().message, kExitFailure);
  stages.push_back({"report", 0, "", drawing.seconds()});
  auto summary = batch::read_demo(a, *plan);
  if (!summary) return fail("demo: " + summary.error().message, kExitFailure);
  if (json.wanted()) {
    nlohmann::json j = to_json(a, *summary);
    j["report"] = *page;
    j["dir"] = a.out;
    j["stages"] = to_json(stages);
    if (!json.emit(j.dump(2) + "\n")) return kExitFailure;
    if (json.print) return kExitOk;
  }
  std::fputs(batch::demo_text(a, *summary).c_str(), stdout);
  std::printf("report:        %s\n", page->c_str());
  return kExitOk;
}

}  // namespace

void add_demo_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo", "Simulate, diagnose, replay (as logged and with corrected clocks), score and report, in one go.");
  cmd->footer(
      "Runs: driftlab sim, diagnose, replay --modules slam,estimator,controller (twice: as logged and with\n"
      "--restamp auto), eval --align posyaw of the estimator's output against ground truth for both, and report.\n"
      "The estimator runs as robot_localization does by default: late measurements are dropped, not re-applied\n"
      "(--estimator-window 0.5 re-applies them, and a skewed clock then costs little: try both).\n"
      "Every stage's output stays in OUT (sim.lcm, diagnosis.json, replay.lcm, restamped.lcm, eval-*.json,\n"
      "report/index.html). Ends with five lines: the worst stream, the clock offsets found, the drops, the ATE\n"
      "before and after correction, and where the report is; --json prints one JSON object instead.");
  cmd->add_option("scenario", a->settings.scenario, "Scenario file (default: the default indoor scenario)");
  cmd->add_option("-o,--out", a->settings.out,
                  "Folder for the logs, JSON and report (default: logs/demo; with --drone, logs/demo-drone)");
  cmd->add_option("--duration", a->settings.duration, "Simulated seconds")
      ->capture_default_str()
      ->check(in_range(kSimDuration, "s"));
  cmd->add_option("--seed", a->settings.seed, "Random seed (default: the scenario's)")->check(in_range(kSeed));
  cmd->add_option("--estimate", a->settings.estimate, "Channel of the replays scored against ground truth")
      ->capture_default_str();
  cmd->add_option("--estimator-window", a->settings.estimator_window,
                  "How far back the estimator re-applies late measurements [s] (0: drops them, as robot_localization)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 60), "s"));  // the estimator's window_s
  cmd->add_flag("--drone", a->settings.drone,
                "The drone's story instead: the clean drone and drone_timebase (SCENARIO: another faulty drone "
                "scenario) simulated, diagnosed, flown again in closed loop with corrected clocks, scored");
  add_json_options(cmd, &a->json, "a summary (report path, ate_before, ate_after in metres, ...)");
  cmd->callback([a, exit_code] {
    if (a->settings.out.empty()) a->settings.out = a->settings.drone ? "logs/demo-drone" : "logs/demo";
    if (Status s = a->json.check({a->settings.scenario}); !s) {
      *exit_code = fail(s.message());
      return;
    }
    *exit_code = run_demo(a->settings, a->json);
  });
}

}  // namespace driftlab::apps
