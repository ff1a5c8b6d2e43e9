#include "batch/demo.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "analyzers/evaluate.h"
#include "analyzers/log_series.h"
#include "core/install_layout.h"
#include "core/number_text.h"
#include "core/process.h"
#include "core/text_file.h"
#include "core/wall_clock.h"
#include "runtime/module_report.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

std::string in_dir(const DemoSettings& s, const std::string& name) { return (fs::path(s.out) / name).string(); }

/// The flights of the drone's story, in the order they are scored.
constexpr const char* kFlights[] = {"clean", "logged", "restamped"};

/// A stage's JSON, read by the library that wrote it. Errors name the file.
template <class T>
Result<T> read_stage(const std::string& path, Result<T> (*read)(const nlohmann::json&)) {
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  auto r = j.is_discarded() ? Result<T>(Error{"not JSON"}) : read(j);
  if (!r) return Error{path + ": " + r.error().message};
  return r;
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

/// The logs of the drone's flights, by name.
std::map<std::string, std::string> drone_flights(const DemoSettings& s) {
  return {
      {"clean", in_dir(s, "clean.lcm")}, {"logged", in_dir(s, "sim.lcm")}, {"restamped", in_dir(s, "restamped.lcm")}};
}

std::vector<std::string> with_seed(const DemoSettings& s, std::vector<std::string> args) {
  if (s.seed >= 0) args.insert(args.end(), {"--seed", std::to_string(s.seed)});
  return args;
}

/// Issue 16's story: the clean drone and drone_timebase (its IMU on a clock 110 ms ahead) simulated, the faulty log
/// diagnosed, flown again in closed loop with the clocks the diagnosis found corrected on board, the three flights
/// scored (setpoint tracking, the estimate's ATE) and drawn.
DemoPlan drone_plan(const DemoSettings& s, const std::string& exe) {
  auto file = [&s](const std::string& name) { return in_dir(s, name); };
  const std::string scenarios = data_path("scenarios").string();
  const std::string faulty = s.scenario.empty() ? scenarios + "/drone_timebase.yaml" : s.scenario;
  auto flights = drone_flights(s);
  DemoPlan p;
  p.stages = {
      {"simulating the clean flight",
       with_seed(s, {exe, "sim", scenarios + "/drone.yaml", "-o", flights["clean"], "--json"}), file("clean.json")},
      {"simulating the faulty flight", with_seed(s, {exe, "sim", faulty, "-o", flights["logged"], "--json"}),
       file("sim.json")},
      {"diagnosing the log",
       {exe, "diagnose", flights["logged"], "--json-out", file("diagnosis.json")},
       file("diagnosis.txt")},
      {"flying again with corrected clocks",
       {exe, "replay", flights["logged"], "--closed-loop", "--restamp", "auto", "-o", flights["restamped"], "--json"},
       file("restamped.json")},
  };
  for (const char* name : kFlights) {
    const std::string& log = flights[name];
    for (const auto& [kind, est, align, what] :
         {std::tuple{"tracking-", "SETPOINT", "posyaw", "scoring the setpoint tracking"},
          std::tuple{"estimate-", "VEHICLE_ODOM", "se3", "scoring the estimate"}}) {
      const std::string stem = kind + std::string(name);
      p.stages.push_back({what,
                          {exe, "eval", "--gt", log + ":GROUND_TRUTH", "--est", log + ":" + est, "--align", align,
                           "--json-out", file(stem + ".json")},
                          file(stem + ".txt")});
    }
  }
  p.report_logs = {flights["logged"], flights["restamped"]};
  p.diagnosis = file("diagnosis.json");
  p.evals = {file("estimate-logged.json"), file("estimate-restamped.json")};
  p.title = "driftlab demo --drone: " + fs::path(faulty).stem().string() + ", as flown and flown again";
  return p;
}

/// The ground robot's story: the default scenario simulated with its faults, diagnosed, replayed through SLAM, the
/// estimator and the controller as logged and with the clocks the diagnosis found corrected, both estimates scored.
Result<DemoPlan> ground_plan(const DemoSettings& s, const std::string& exe) {
  auto file = [&s](const std::string& name) { return in_dir(s, name); };
  const std::string sim = file("sim.lcm"), replay = file("replay.lcm"), restamped = file("restamped.lcm");
  std::vector<std::string> sim_args = {exe, "sim"};
  if (!s.scenario.empty()) sim_args.push_back(s.scenario);
  char duration[32];
  std::snprintf(duration, sizeof(duration), "%g", s.duration);
  sim_args.insert(sim_args.end(), {"--duration", duration, "-o", sim, "--json"});
  // The estimator as robot_localization runs by default (smooth_lagged_data: false): a measurement stamped before
  // the filter's last update is dropped, not re-applied. That is where a skewed clock hurts a real robot.
  const std::string config = file("replay.yaml");
  std::ostringstream c;
  c << "# Written by driftlab demo: the estimator re-applies late measurements within window_s [s]; 0 drops them,\n"
       "# as robot_localization does by default (smooth_lagged_data: false).\n"
       "estimator:\n  window_s: "
    << s.estimator_window << "\n";
  if (Status st = write_file_atomically(config, c.str()); !st) return st.error();
  const std::string modules = "slam,estimator,controller", gt = sim + ":GROUND_TRUTH";
  DemoPlan p;
  p.stages = {
      {"simulating the robot", with_seed(s, sim_args), file("sim.json")},
      {"diagnosing the log", {exe, "diagnose", sim, "--json-out", file("diagnosis.json")}, file("diagnosis.txt")},
      {"replaying as logged",
       {exe, "replay", sim, "--modules", modules, "--config", config, "-o", replay, "--json"},
       file("replay.json")},
      {"replaying with corrected clocks",
       {exe, "replay", sim, "--modules", modules, "--config", config, "--restamp", "auto", "-o", restamped, "--json"},
       file("restamped.json")},
  };
  for (const auto& [log, stem] : {std::pair{replay, "eval-before"}, std::pair{restamped, "eval-after"}}) {
    p.stages.push_back({"scoring the estimates",
                        {exe, "eval", "--gt", gt, "--est", log + ":" + s.estimate, "--align", "posyaw", "--json-out",
                         file(std::string(stem) + ".json")},
                        file(std::string(stem) + ".txt")});
  }
  p.report_logs = {sim, replay, restamped};
  p.diagnosis = file("diagnosis.json");
  p.evals = {file("eval-before.json"), file("eval-after.json")};
  p.title = std::string("driftlab demo: ") + duration + " s of " +
            (s.scenario.empty() ? std::string("the default scenario") : fs::path(s.scenario).stem().string());
  return p;
}

/// The worst stream with its first reason, and the clocks found ahead.
std::string worst_and_clocks(const analyzers::DiagnosisSummary& summary) {
  std::string worst_text = "none: no stream was flagged";
  if (const auto& worst = summary.worst_stream) {
    worst_text = worst->name + " (" + analyzers::severity_name(worst->verdict) + ")";
    if (!worst->reasons.empty()) worst_text += ": " + worst->reasons[0];
  }
  std::string offsets;
  for (const auto& [name, v] : summary.clocks_ahead_s) {
    appendf(offsets, "%s%s %+.1f ms", offsets.empty() ? "" : ", ", name.c_str(), v * 1e3);
  }
  return "\nworst stream:  " + worst_text +
         "\nclocks ahead:  " + (offsets.empty() ? "none by more than 1 ms" : offsets) + "\n";
}

}  // namespace

Result<DemoPlan> plan_demo(const DemoSettings& settings, const std::string& exe) {
  auto p = settings.drone ? Result<DemoPlan>(drone_plan(settings, exe)) : ground_plan(settings, exe);
  if (!p) return p;
  p->report_dir = in_dir(settings, "report");
  p->report_command = {exe, "report"};
  p->report_command.insert(p->report_command.end(), p->report_logs.begin(), p->report_logs.end());
  p->report_command.insert(p->report_command.end(), {"--diagnosis", p->diagnosis});
  for (const auto& e : p->evals) p->report_command.insert(p->report_command.end(), {"--eval", e});
  p->report_command.insert(p->report_command.end(), {"-o", p->report_dir});
  return p;
}

std::vector<StageRun> run_stages(const DemoPlan& plan, const std::string& dir,
                                 const std::function<void(size_t, const std::function<void()>&)>& around) {
  std::error_code ec;
  const std::string errors = (fs::path(dir) / "stage.err").string();
  std::vector<StageRun> runs;
  for (size_t i = 0; i < plan.stages.size(); ++i) {
    const DemoStage& s = plan.stages[i];
    StageRun run{s.args.at(1)};
    const Stopwatch stage;
    around(i, [&] { run.code = run_process(s.args, s.stdout_file, errors); });
    run.seconds = stage.seconds();
    if (run.code != 0) {
      run.said = last_line_of(errors);
      fs::remove(s.stdout_file, ec);
    }
    runs.push_back(std::move(run));
    if (runs.back().code != 0) break;
  }
  fs::remove(errors, ec);
  return runs;
}

std::string command_text(const std::vector<std::string>& args) {
  std::string s = "driftlab";
  for (size_t i = 1; i < args.size(); ++i) s += " " + args[i];
  return s;
}

nlohmann::json to_json(const std::vector<StageRun>& stages) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : stages) out.push_back({{"name", s.name}, {"seconds", s.seconds}});
  return out;
}

double ImuRejections::percent() const {
  return received > 0 ? 100.0 * static_cast<double>(rejected) / static_cast<double>(received) : 0.0;
}

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

Result<DemoSummary> read_demo(const DemoSettings& settings, const DemoPlan& plan) {
  DemoSummary out;
  auto summary = read_stage(plan.diagnosis, analyzers::summarize);
  if (!summary) return summary.error();
  out.diagnosis = std::move(*summary);
  if (settings.drone) {
    for (const char* name : kFlights) {
      for (auto& [kind, into] :
           {std::pair{"tracking-", &out.tracking_m}, std::pair{"estimate-", &out.estimate_ate_m}}) {
        auto eval = read_stage(in_dir(settings, kind + std::string(name) + ".json"), analyzers::evaluation_headline);
        if (!eval) return eval.error();
        (*into)[name] = eval->ate_rmse;
      }
    }
    auto flights = drone_flights(settings);
    out.imu_logged = imu_rejections(flights["logged"]);
    out.imu_restamped = imu_rejections(flights["restamped"]);
    return out;
  }
  for (auto [eval, ate] : {std::pair{plan.evals.at(0), &out.ate_before}, std::pair{plan.evals.at(1), &out.ate_after}}) {
    auto headline = read_stage(eval, analyzers::evaluation_headline);
    if (!headline) return headline.error();
    *ate = headline->ate_rmse;
  }
  for (auto [name, n] :
       {std::pair{"replay.json", &out.late_rejected_before}, std::pair{"restamped.json", &out.late_rejected_after}}) {
    auto rejected = late_rejected(in_dir(settings, name));
    if (!rejected) return rejected.error();
    *n = *rejected;
  }
  return out;
}

nlohmann::json to_json(const DemoSettings& settings, const DemoSummary& s) {
  nlohmann::json j;
  const nlohmann::json headline = to_json(s.diagnosis);
  j["worst_stream"] = headline["worst_stream"];
  j["clock_offsets_s"] = headline["clocks_ahead_s"];
  if (settings.drone) {
    j["tracking_m"] = s.tracking_m;
    j["estimate_ate_m"] = s.estimate_ate_m;
    j["imu_rejected"] = {{"logged", s.imu_logged.rejected}, {"restamped", s.imu_restamped.rejected}};
    j["imu_received"] = {{"logged", s.imu_logged.received}, {"restamped", s.imu_restamped.received}};
    return j;
  }
  j["estimate"] = settings.estimate;
  j["ate_before"] = s.ate_before;
  j["ate_after"] = s.ate_after;
  j["late_rejected_before"] = s.late_rejected_before;
  j["late_rejected_after"] = s.late_rejected_after;
  j["drops"] = headline["drops"];
  return j;
}

std::string demo_text(const DemoSettings& settings, const DemoSummary& s) {
  std::string out = worst_and_clocks(s.diagnosis);
  if (settings.drone) {
    auto at = [](const std::map<std::string, double>& m, const char* k) {
      auto it = m.find(k);
      return it == m.end() ? 0.0 : it->second;
    };
    appendf(out,
            "estimator:     rejected %.0f%% of its IMU samples (%s of %s, %s from the future) as logged, %.0f%% "
            "flown again\n",
            s.imu_logged.percent(), thousands(s.imu_logged.rejected).c_str(), thousands(s.imu_logged.received).c_str(),
            thousands(s.imu_logged.future).c_str(), s.imu_restamped.percent());
    appendf(out,
            "flight error:  setpoints tracked to %.3f m as logged, %.3f m flown again (clean run %.3f m); estimate "
            "ATE %.3f m, %.3f m (clean %.3f m)\n",
            at(s.tracking_m, "logged"), at(s.tracking_m, "restamped"), at(s.tracking_m, "clean"),
            at(s.estimate_ate_m, "logged"), at(s.estimate_ate_m, "restamped"), at(s.estimate_ate_m, "clean"));
    return out;
  }
  std::string drops;
  for (const auto& [name, n] : s.diagnosis.drops) drops += (drops.empty() ? "" : ", ") + name + " " + thousands(n);
  appendf(out, "drops:         %s\n", drops.empty() ? "none" : drops.c_str());
  appendf(out,
          "ATE:           %s %.3f m as logged, %.3f m with corrected clocks (%+.0f%%; late measurements dropped: %s, "
          "then %s)\n",
          settings.estimate.c_str(), s.ate_before, s.ate_after,
          s.ate_before > 0 ? (s.ate_after - s.ate_before) / s.ate_before * 100 : 0.0,
          thousands(s.late_rejected_before).c_str(), thousands(s.late_rejected_after).c_str());
  return out;
}

}  // namespace driftlab::batch
