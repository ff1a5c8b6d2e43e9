// driftlab demo: the first thing a new user runs. Simulates the default scenario with its faults, diagnoses the
// log, replays it through SLAM, the estimator and the controller as logged and again with the clocks the
// diagnosis found corrected, scores both estimates against ground truth and writes the report. Each stage is this
// program run again with the stage's subcommand (as `git` runs its own), its JSON kept in the output folder, so
// every number the demo prints can be reproduced with the command it shows.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>

#include "analyzers/diagnosis_json.h"
#include "analyzers/evaluate.h"
#include "analyzers/log_series.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/report.h"
#include "core/install_layout.h"
#include "core/process.h"
#include "core/wall_clock.h"
#include "runtime/module_report.h"

namespace driftlab::apps {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  std::string scenario;
  std::string out;  ///< default: logs/demo, or logs/demo-drone with --drone (one story's files never over the other's)
  double duration = 120;
  int64_t seed = -1;
  std::string estimate = "EKF_ODOM";
  double estimator_window = 0;
  bool drone = false;
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

/// A stage's JSON, read by the library that wrote it. Errors name the file.
template <class T>
Result<T> read_stage(const std::string& path, Result<T> (*read)(const nlohmann::json&)) {
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  auto r = j.is_discarded() ? Result<T>(Error{"not JSON"}) : read(j);
  if (!r) return Error{path + ": " + r.error().message};
  return r;
}

/// The first error among results, if any.
template <class... R>
std::optional<Error> first_error(const R&... results) {
  std::optional<Error> e;
  ((e || results ? void() : void(e = results.error())), ...);
  return e;
}

/// Late measurements the estimator dropped, from `driftlab replay --json`.
Result<int64_t> late_rejected(const std::string& replay_json) {
  auto reports = read_stage(replay_json, runtime::module_reports_from_json);
  if (!reports) return reports.error();
  for (const auto& m : *reports) {
    if (m.name == "estimator") return static_cast<int64_t>(runtime::metric(m, "late_rejected").value_or(0));
  }
  return 0;
}

/// The summary's first two lines: the worst stream with its first reason, and the clocks found ahead.
void print_worst_and_clocks(const analyzers::DiagnosisSummary& summary) {
  std::string worst_text = "none: no stream was flagged";
  if (const auto& worst = summary.worst_stream) {
    worst_text = worst->name + " (" + analyzers::severity_name(worst->verdict) + ")";
    if (!worst->reasons.empty()) worst_text += ": " + worst->reasons[0];
  }
  std::string offset_text;
  char buf[160];
  for (const auto& [name, v] : summary.clocks_ahead_s) {
    std::snprintf(buf, sizeof(buf), "%s%s %+.1f ms", offset_text.empty() ? "" : ", ", name.c_str(), v * 1e3);
    offset_text += buf;
  }
  std::printf("\nworst stream:  %s\n", worst_text.c_str());
  std::printf("clocks ahead:  %s\n", offset_text.empty() ? "none by more than 1 ms" : offset_text.c_str());
}

/// The stages' names and times, for --json.
nlohmann::json stages_json(const std::vector<Stage>& stages) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : stages) out.push_back({{"name", s.name}, {"seconds", s.seconds}});
  return out;
}

struct Step {
  const char* what;
  std::vector<std::string> args;
  std::string stdout_file;
};

/// Runs the steps in turn, each a driftlab subcommand with its output kept in its file, and notes their times in
/// `stages`; `total` counts them and the report after them. The exit code of the first that fails (the demo's:
/// 2 when it was given bad input, 1 otherwise), with its last error line, or 0.
int run_steps(const std::vector<Step>& steps, int total, bool json, const fs::path& dir, std::vector<Stage>& stages) {
  std::error_code ec;
  const std::string errors = (dir / "stage.err").string();
  for (size_t i = 0; i < steps.size(); ++i) {
    const Step& s = steps[i];
    if (!json) std::printf("== %s\n", join_args(s.args).c_str());
    std::fflush(stdout);
    const Stopwatch stage;
    int code = 0;
    {
      StageLine line(stage_label(static_cast<int>(i) + 1, total, s.what));
      // The stage's errors go to a file (its progress would fight with ours): the last line is the one to show.
      code = run_program(s.args, s.stdout_file, errors);
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
Result<std::string> draw_report(const ReportOptions& r, int total, bool json, std::vector<Stage>& stages) {
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
    page = make_report(r);
  }
  if (page) stages.push_back({"report", drawing.seconds()});
  return page;
}

/// What the drone's estimator did with its IMU: rejected (stale, future or late) of all it received, and how many
/// of the rejections were from the future, from the last driftlab.estimator_status_t of a log.
struct ImuRejections {
  int64_t rejected = 0, received = 0, future = 0;
};
ImuRejections imu_rejections(const std::string& log) {
  ImuRejections out;
  auto series = analyzers::read_log_series(log, "ESTIMATOR_STATUS");
  if (!series || series->estimators.empty()) return out;
  const analyzers::EstimatorSeries& s = series->estimators.front();
  if (s.inputs.empty() || s.inputs[0] != "imu" || s.t.empty()) return out;
  out.future = s.future[0].back();
  out.rejected = s.stale[0].back() + s.future[0].back() + s.late[0].back();
  out.received = out.rejected + s.fused[0].back() + s.outliers[0].back();
  return out;
}

/// `driftlab demo --drone`: issue 16's story. The clean drone and drone_timebase (its IMU on a clock 110 ms ahead)
/// simulated, the faulty log diagnosed, flown again in closed loop with the clocks the diagnosis found corrected on
/// board, the three flights scored (setpoint tracking, the estimate's ATE) and drawn.
int run_drone_demo(const DemoArgs& a, const fs::path& dir, const std::string& exe) {
  auto file = [&](const char* name) { return (dir / name).string(); };
  const std::string scenarios = data_path("scenarios").string();
  const std::string faulty_scenario = a.scenario.empty() ? scenarios + "/drone_timebase.yaml" : a.scenario;
  const std::string clean = file("clean.lcm"), sim = file("sim.lcm"), restamped = file("restamped.lcm");
  std::vector<std::string> seed;
  if (a.seed >= 0) seed = {"--seed", std::to_string(a.seed)};
  auto with_seed = [&](std::vector<std::string> args) {
    args.insert(args.end(), seed.begin(), seed.end());
    return args;
  };
  std::vector<Step> steps = {
      {"simulating the clean flight", with_seed({exe, "sim", scenarios + "/drone.yaml", "-o", clean, "--json"}),
       file("clean.json")},
      {"simulating the faulty flight", with_seed({exe, "sim", faulty_scenario, "-o", sim, "--json"}), file("sim.json")},
      {"diagnosing the log", {exe, "diagnose", sim, "--json-out", file("diagnosis.json")}, file("diagnosis.txt")},
      {"flying again with corrected clocks",
       {exe, "replay", sim, "--closed-loop", "--restamp", "auto", "-o", restamped, "--json"},
       file("restamped.json")},
  };
  const std::pair<const char*, std::string> flights[] = {{"clean", clean}, {"logged", sim}, {"restamped", restamped}};
  for (const auto& [name, log] : flights) {
    steps.push_back({"scoring the setpoint tracking",
                     {exe, "eval", "--gt", log + ":GROUND_TRUTH", "--est", log + ":SETPOINT", "--align", "posyaw",
                      "--json-out", file((std::string("tracking-") + name + ".json").c_str())},
                     file((std::string("tracking-") + name + ".txt").c_str())});
    steps.push_back({"scoring the estimate",
                     {exe, "eval", "--gt", log + ":GROUND_TRUTH", "--est", log + ":VEHICLE_ODOM", "--align", "se3",
                      "--json-out", file((std::string("estimate-") + name + ".json").c_str())},
                     file((std::string("estimate-") + name + ".txt").c_str())});
  }
  const int total = static_cast<int>(steps.size()) + 1;
  std::vector<Stage> stages;
  if (int code = run_steps(steps, total, a.json.print, dir, stages); code != kExitOk) return code;

  ReportOptions r;
  r.logs = {sim, restamped};
  r.out = file("report");
  r.diagnosis = file("diagnosis.json");
  r.evals = {file("estimate-logged.json"), file("estimate-restamped.json")};
  r.title = "driftlab demo --drone: " + fs::path(faulty_scenario).stem().string() + ", as flown and flown again";
  auto page = draw_report(r, total, a.json.print, stages);
  if (!page) return fail("demo: " + page.error().message, kExitFailure);

  auto summary = read_stage(r.diagnosis, analyzers::summarize);
  if (!summary) return fail("demo: " + summary.error().message, kExitFailure);
  std::map<std::string, double> tracking, estimate;
  for (const auto& [name, log] : flights) {
    for (auto& [kind, into] : {std::pair{"tracking-", &tracking}, std::pair{"estimate-", &estimate}}) {
      auto eval = read_stage(file((kind + std::string(name) + ".json").c_str()), analyzers::evaluation_headline);
      if (!eval) return fail("demo: " + eval.error().message, kExitFailure);
      (*into)[name] = eval->ate_rmse;
    }
  }
  const ImuRejections before = imu_rejections(sim), after = imu_rejections(restamped);
  auto percent = [](const ImuRejections& r) {
    return r.received > 0 ? 100.0 * static_cast<double>(r.rejected) / static_cast<double>(r.received) : 0.0;
  };
  if (a.json.wanted()) {
    nlohmann::json j;
    j["report"] = *page;
    j["dir"] = a.out;
    j["tracking_m"] = tracking;
    j["estimate_ate_m"] = estimate;
    j["imu_rejected"] = {{"logged", before.rejected}, {"restamped", after.rejected}};
    j["imu_received"] = {{"logged", before.received}, {"restamped", after.received}};
    const nlohmann::json headline = to_json(*summary);
    j["worst_stream"] = headline["worst_stream"];
    j["clock_offsets_s"] = headline["clocks_ahead_s"];
    j["stages"] = stages_json(stages);
    if (!a.json.emit(j.dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  print_worst_and_clocks(*summary);
  std::printf(
      "estimator:     rejected %.0f%% of its IMU samples (%s of %s, %s from the future) as logged, %.0f%% "
      "flown again\n",
      percent(before), thousands(before.rejected).c_str(), thousands(before.received).c_str(),
      thousands(before.future).c_str(), percent(after));
  std::printf(
      "flight error:  setpoints tracked to %.3f m as logged, %.3f m flown again (clean run %.3f m); estimate "
      "ATE %.3f m, %.3f m (clean %.3f m)\n",
      tracking["logged"], tracking["restamped"], tracking["clean"], estimate["logged"], estimate["restamped"],
      estimate["clean"]);
  std::printf("report:        %s\n", page->c_str());
  return kExitOk;
}

int run_demo(const DemoArgs& a) {
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) return fail(a.out + ": cannot create the demo folder: " + ec.message());
  const fs::path dir(a.out);
  const std::string exe = self_path();
  if (a.drone) return run_drone_demo(a, dir, exe);
  auto file = [&](const char* name) { return (dir / name).string(); };
  const std::string sim = file("sim.lcm"), replay = file("replay.lcm"), restamped = file("restamped.lcm");
  const std::string report_dir = file("report");

  std::vector<std::string> sim_args = {exe, "sim"};
  if (!a.scenario.empty()) sim_args.push_back(a.scenario);
  char duration[32];
  std::snprintf(duration, sizeof(duration), "%g", a.duration);
  sim_args.insert(sim_args.end(), {"--duration", duration, "-o", sim, "--json"});
  if (a.seed >= 0) sim_args.insert(sim_args.end(), {"--seed", std::to_string(a.seed)});
  // The estimator as robot_localization runs by default (smooth_lagged_data: false): a measurement stamped before
  // the filter's last update is dropped, not re-applied. That is where a skewed clock hurts a real robot.
  const std::string config = file("replay.yaml");
  {
    std::ofstream c(config);
    c << "# Written by driftlab demo: the estimator re-applies late measurements within window_s [s]; 0 drops them,\n"
         "# as robot_localization does by default (smooth_lagged_data: false).\n"
         "estimator:\n  window_s: "
      << a.estimator_window << "\n";
    if (!c) return fail(config + ": cannot write", kExitFailure);
  }
  const std::string modules = "slam,estimator,controller";
  const std::string gt = sim + ":GROUND_TRUTH";
  const std::vector<Step> steps = {
      {"simulating the robot", sim_args, file("sim.json")},
      {"diagnosing the log", {exe, "diagnose", sim, "--json-out", file("diagnosis.json")}, file("diagnosis.txt")},
      {"replaying as logged",
       {exe, "replay", sim, "--modules", modules, "--config", config, "-o", replay, "--json"},
       file("replay.json")},
      {"replaying with corrected clocks",
       {exe, "replay", sim, "--modules", modules, "--config", config, "--restamp", "auto", "-o", restamped, "--json"},
       file("restamped.json")},
      {"scoring the estimates",
       {exe, "eval", "--gt", gt, "--est", replay + ":" + a.estimate, "--align", "posyaw", "--json-out",
        file("eval-before.json")},
       file("eval-before.txt")},
      {"scoring the estimates",
       {exe, "eval", "--gt", gt, "--est", restamped + ":" + a.estimate, "--align", "posyaw", "--json-out",
        file("eval-after.json")},
       file("eval-after.txt")},
  };
  const int total = static_cast<int>(steps.size()) + 1;
  std::vector<Stage> stages;
  if (int code = run_steps(steps, total, a.json.print, dir, stages); code != kExitOk) return code;

  ReportOptions r;
  r.logs = {sim, replay, restamped};
  r.out = report_dir;
  r.diagnosis = file("diagnosis.json");
  r.evals = {file("eval-before.json"), file("eval-after.json")};
  r.title = std::string("driftlab demo: ") + duration + " s of " +
            (a.scenario.empty() ? std::string("the default scenario") : fs::path(a.scenario).stem().string());
  auto page = draw_report(r, total, a.json.print, stages);
  if (!page) return fail("demo: " + page.error().message, kExitFailure);

  // The summary, from the stages' JSON.
  auto summary = read_stage(r.diagnosis, analyzers::summarize);
  auto before = read_stage(r.evals[0], analyzers::evaluation_headline);
  auto after = read_stage(r.evals[1], analyzers::evaluation_headline);
  auto rejected_before = late_rejected(file("replay.json")), rejected_after = late_rejected(file("restamped.json"));
  if (auto e = first_error(summary, before, after, rejected_before, rejected_after)) {
    return fail("demo: " + e->message, kExitFailure);
  }
  if (a.json.wanted()) {
    nlohmann::json j;
    j["report"] = *page;
    j["dir"] = a.out;
    j["estimate"] = a.estimate;
    j["ate_before"] = before->ate_rmse;
    j["ate_after"] = after->ate_rmse;
    j["late_rejected_before"] = *rejected_before;
    j["late_rejected_after"] = *rejected_after;
    const nlohmann::json headline = to_json(*summary);
    j["worst_stream"] = headline["worst_stream"];
    j["clock_offsets_s"] = headline["clocks_ahead_s"];
    j["drops"] = headline["drops"];
    j["stages"] = stages_json(stages);
    if (!a.json.emit(j.dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::string drop_text;
  for (const auto& [name, n] : summary->drops) drop_text += (drop_text.empty() ? "" : ", ") + name + " " + thousands(n);
  print_worst_and_clocks(*summary);
  std::printf("drops:         %s\n", drop_text.empty() ? "none" : drop_text.c_str());
  std::printf(
      "ATE:           %s %.3f m as logged, %.3f m with corrected clocks (%+.0f%%; late measurements "
      "dropped: %s, then %s)\n",
      a.estimate.c_str(), before->ate_rmse, after->ate_rmse,
      before->ate_rmse > 0 ? (after->ate_rmse - before->ate_rmse) / before->ate_rmse * 100 : 0.0,
      thousands(*rejected_before).c_str(), thousands(*rejected_after).c_str());
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
  cmd->add_option("scenario", a->scenario, "Scenario file (default: the default indoor scenario)");
  cmd->add_option("-o,--out", a->out,
                  "Folder for the logs, JSON and report (default: logs/demo; with --drone, logs/demo-drone)");
  cmd->add_option("--duration", a->duration, "Simulated seconds")
      ->capture_default_str()
      ->check(in_range(kSimDuration, "s"));
  cmd->add_option("--seed", a->seed, "Random seed (default: the scenario's)")->check(in_range(kSeed));
  cmd->add_option("--estimate", a->estimate, "Channel of the replays scored against ground truth")->capture_default_str();
  cmd->add_option("--estimator-window", a->estimator_window,
                  "How far back the estimator re-applies late measurements [s] (0: drops them, as robot_localization)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 60), "s"));  // the estimator's window_s
  cmd->add_flag("--drone", a->drone,
                "The drone's story instead: the clean drone and drone_timebase (SCENARIO: another faulty drone "
                "scenario) simulated, diagnosed, flown again in closed loop with corrected clocks, scored");
  add_json_options(cmd, &a->json, "a summary (report path, ate_before, ate_after in metres, ...)");
  cmd->callback([a, exit_code] {
    if (a->out.empty()) a->out = a->drone ? "logs/demo-drone" : "logs/demo";
    if (Status s = a->json.check({a->scenario}); !s) {
      *exit_code = fail(s.message());
      return;
    }
    *exit_code = run_demo(*a);
  });
}

}  // namespace driftlab::apps
