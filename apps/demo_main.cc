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
#include "core/process.h"
#include "core/progress_line.h"
#include "core/wall_clock.h"
#include "report/report.h"

namespace driftlab::apps {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  batch::DemoSettings
      settings;  ///< out: default logs/demo, or logs/demo-drone with --drone (one story's files never over the other's)
  JsonOutput json;
};

/// "[3/7] replaying the log".
std::string stage_label(int index, int total, const std::string& what) {
  return "[" + std::to_string(index) + "/" + std::to_string(total) + "] " + what;
}

struct Stage {
  std::string name;
  double seconds = 0;
};

std::string join_args(const std::vector<std::string>& args) {
  std::string s = "driftlab";
  for (size_t i = 1; i < args.size(); ++i) s += " " + args[i];
  return s;
}

/// The stages' names and times, for --json.
nlohmann::json stages_json(const std::vector<Stage>& stages) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : stages) out.push_back({{"name", s.name}, {"seconds", s.seconds}});
  return out;
}

/// Runs the steps in turn, each a driftlab subcommand with its output kept in its file, and notes their times in
/// `stages`; `total` counts them and the report after them. The exit code of the first that fails (the demo's:
/// 2 when it was given bad input, 1 otherwise), with its last error line, or 0.
int run_steps(const std::vector<batch::DemoStage>& steps, int total, bool json, const fs::path& dir,
              std::vector<Stage>& stages) {
  std::error_code ec;
  const std::string errors = (dir / "stage.err").string();
  for (size_t i = 0; i < steps.size(); ++i) {
    const batch::DemoStage& s = steps[i];
    if (!json) std::printf("== %s\n", join_args(s.args).c_str());
    std::fflush(stdout);
    const Stopwatch stage;
    int code = 0;
    {
      StageLine line(stage_label(static_cast<int>(i) + 1, total, s.what));
      // The stage's errors go to a file (its progress would fight with ours): the last line is the one to show.
      code = run_process(s.args, s.stdout_file, errors);
    }
    stages.push_back({s.args[1], stage.seconds()});
    if (code != 0) {
      const std::string why = last_line_of(errors);
      // The failed stage's output is not kept (it is empty or cut short).
      fs::remove(s.stdout_file, ec);
      fs::remove(errors, ec);
      return fail("demo: " + join_args(s.args) + " failed (exit " + std::to_string(code) + ")" +
                      (why.empty() ? "" : ": " + why),
                  code == kExitBadInput ? kExitBadInput : kExitFailure);
    }
  }
  fs::remove(errors, ec);
  return kExitOk;
}

/// Draws the report as the demo's last stage.
Result<std::string> draw_report(const report::ReportOptions& r, int total, bool json, std::vector<Stage>& stages) {
  if (!json) {
    std::printf("== driftlab report");
    for (const auto& log : r.logs) std::printf(" %s", log.c_str());
    std::printf(" --diagnosis %s", r.diagnosis.c_str());
    for (const auto& e : r.evals) std::printf(" --eval %s", e.c_str());
    std::printf(" -o %s\n", r.out.c_str());
  }
  std::fflush(stdout);
  const Stopwatch drawing;
  Result<std::string> page = Error{""};
  {
    StageLine line(stage_label(total, total, "drawing the report"));
    page = report::make_report(r);
  }
  if (page) stages.push_back({"report", drawing.seconds()});
  return page;
}

int run_demo(const batch::DemoSettings& a, const JsonOutput& json) {
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) return fail(a.out + ": cannot create the demo folder: " + ec.message());
  auto plan = batch::plan_demo(a, self_path());
  if (!plan) return fail("demo: " + plan.error().message, kExitFailure);
  const int total = static_cast<int>(plan->stages.size()) + 1;
  std::vector<Stage> stages;
  if (int code = run_steps(plan->stages, total, json.print, a.out, stages); code != kExitOk) return code;

  report::ReportOptions r;
  r.logs = plan->report_logs;
  r.out = plan->report_dir;
  r.diagnosis = plan->diagnosis;
  r.evals = plan->evals;
  r.title = plan->title;
  auto page = draw_report(r, total, json.print, stages);
  if (!page) return fail("demo: " + page.error().message, kExitFailure);
  auto summary = batch::read_demo(a, *plan);
  if (!summary) return fail("demo: " + summary.error().message, kExitFailure);
  if (json.wanted()) {
    nlohmann::json j = to_json(a, *summary);
    j["report"] = *page;
    j["dir"] = a.out;
    j["stages"] = stages_json(stages);
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
