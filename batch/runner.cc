#include "batch/runner.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "analyzers/diagnosis_json.h"
#include "batch/store.h"
#include "core/process.h"
#include "core/text_file.h"
#include "core/wall_clock.h"
#include "runtime/module_report.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

volatile sig_atomic_t g_stop = 0;
volatile sig_atomic_t g_child = 0;

void on_signal(int sig) {
  g_stop = 1;
  // A terminal's Ctrl-C reaches the stage itself; a SIGTERM from an executor or scancel reaches only us.
  if (g_child > 0) ::kill(static_cast<pid_t>(g_child), sig);
}

struct StageRun {
  std::string name;
  std::vector<std::string> argv;
  std::string out;  ///< its standard output
};

}  // namespace

nlohmann::json point_metrics(const Plan& plan, const std::string& pdir) {
  const Spec& s = plan.spec;
  const fs::path d(pdir);
  nlohmann::json m = nlohmann::json::object();
  if (s.has(Stage::kEval)) {
    if (auto e = read_json_file((d / "eval.json").string())) {
      m["ate_rmse"] = (*e).at("ate").at("rmse");
      m["ate_max"] = (*e).at("ate").at("max");
      m["rpe_rmse"] = (*e).at("rpe").at("trans").at("rmse");
      m["matched_poses"] = (*e).at("matched");
    }
  }
  if (s.has(Stage::kDiagnose)) {
    if (auto dj = read_json_file((d / "diagnosis.json").string())) {
      if (auto sum = analyzers::summarize(*dj)) {
        int64_t drops = 0;
        for (const auto& [ch, n] : sum->drops) {
          m["drops." + ch] = n;
          drops += n;
        }
        m["drops"] = drops;
        for (const auto& [ch, v] : sum->clocks_ahead_s) m["offset_s." + ch] = v;
        const auto& worst = sum->worst_stream;
        m["worst_stream"] = worst ? worst->name : "";
        m["worst_verdict"] = analyzers::severity_name(worst ? worst->verdict : analyzers::Severity::kOk);
        m["worst_reason"] = worst && !worst->reasons.empty() ? worst->reasons[0] : "";
        m["fault_streams"] = sum->fault_streams;
        m["warn_streams"] = sum->warn_streams;
      }
    }
  }
  if (s.has(Stage::kReplay)) {
    auto r = read_json_file((d / "replay.json").string());
    auto reports = r ? runtime::module_reports_from_json(*r) : Result<std::vector<runtime::ModuleReport>>(r.error());
    for (const auto& mod : reports ? *reports : std::vector<runtime::ModuleReport>{}) {
      if (mod.name != "estimator") continue;
      for (const char* k : {"late_rejected", "late_reapplied"}) {
        if (auto v = runtime::metric(mod, k)) m[std::string("estimator.") + k] = *v;
      }
    }
  }
  if (s.has(Stage::kReport)) m["report"] = (d / "report" / "index.html").string();
  return m;
}

int run_point(const Plan& plan, const Point& point, const std::string& dir, const RunnerOptions& options,
              const WallClock& clock) {
  const Spec& s = plan.spec;
  if (is_done(dir, point.id)) return kPointDone;
  const fs::path d = fs::absolute(point_dir(dir, point.id));
  std::error_code ec;
  // A new attempt starts clean: what an earlier, unfinished one left is removed (the attempt count stays).
  if (fs::exists(d)) {
    for (const auto& e : fs::directory_iterator(d, ec)) {
      if (e.path().filename() != "attempts") fs::remove_all(e.path(), ec);
    }
  }
  fs::create_directories(d, ec);
  if (ec) {
    std::fprintf(stderr, "driftlab: %s: cannot create the point's folder: %s\n", d.c_str(), ec.message().c_str());
    return kPointFailed;
  }
  const int attempt = count_attempt(dir, point.id);
  auto file = [&](const char* name) { return (d / name).string(); };
  nlohmann::json running = {{"host", host_name()},
                            {"pid", static_cast<int>(::getpid())},
                            {"attempt", attempt},
                            {"started", clock.now().us() / 1000000}};  // [s since the epoch]
  if (const char* job = std::getenv("SLURM_JOB_ID")) running["slurm_job"] = job;
  (void)write_file_atomically(file("running.json"), running.dump() + "\n", kSynced);

  nlohmann::json params = nlohmann::json::object();
  for (const auto& [k, v] : point.params) params[k] = v.json();
  (void)write_file_atomically(file("params.json"), params.dump(1) + "\n", kSynced);

  // The point's inputs.
  const std::string faults = faults_yaml(s, point), config = module_config_yaml(s, point);
  if (!faults.empty()) (void)write_file_atomically(file("faults.yaml"), faults, kSynced);
  if (!config.empty()) (void)write_file_atomically(file("replay.yaml"), config, kSynced);
  const Value* log = point.get("log");
  const std::string input = log != nullptr ? log->text : file("sim.lcm");
  const Value* seed = point.get("seed");
  const Value* duration = point.get("duration");
  const std::string restamp = restamp_of(s, point);
  const bool logs_with_faults = log != nullptr && !faults.empty();

  const std::string& exe = options.driftlab;
  std::vector<StageRun> stages;
  for (Stage st : s.stages) {
    StageRun r{stage_name(st), {exe, stage_name(st)}, ""};
    switch (st) {
      case Stage::kSim:
        r.argv.push_back(s.scenario);
        r.argv.insert(r.argv.end(), {"-o", file("sim.lcm"), "--json"});
        if (seed != nullptr || s.seed >= 0) r.argv.insert(r.argv.end(), {"--seed", seed ? seed->text : std::to_string(s.seed)});
        if (duration != nullptr) {
          r.argv.insert(r.argv.end(), {"--duration", duration->text});
        } else if (s.duration > 0) {
          r.argv.insert(r.argv.end(), {"--duration", Value::of_number(s.duration).text});
        }
        if (!faults.empty()) r.argv.insert(r.argv.end(), {"--faults", file("faults.yaml")});
        r.out = file("sim.json");
        break;
      case Stage::kReplay:
        r.argv.insert(r.argv.end(), {input, "--modules", s.modules, "-o", file("replay.lcm"), "--json"});
        if (!config.empty()) r.argv.insert(r.argv.end(), {"--config", file("replay.yaml")});
        if (restamp == "auto") r.argv.insert(r.argv.end(), {"--restamp", "auto"});
        if (logs_with_faults) r.argv.insert(r.argv.end(), {"--inject", file("faults.yaml")});
        // The inputs are needed in the output only when the faults were injected here and the diagnosis reads them.
        if (!(logs_with_faults && s.has(Stage::kDiagnose))) r.argv.push_back("--no-inputs");
        r.out = file("replay.json");
        break;
      case Stage::kDiagnose:
        r.argv.insert(r.argv.end(), {logs_with_faults && s.has(Stage::kReplay) ? file("replay.lcm") : input,
                                     "--json-out", file("diagnosis.json")});
        r.out = file("diagnose.txt");
        break;
      case Stage::kEval: {
        const std::string est_log = s.has(Stage::kReplay) ? file("replay.lcm") : input;
        r.argv.insert(r.argv.end(), {"--gt", input + ":" + s.gt_channel, "--est", est_log + ":" + s.est_channel,
                                     "--align", s.align, "--json-out", file("eval.json")});
        r.out = file("eval.txt");
        break;
      }
      case Stage::kReport:
        r.argv.insert(r.argv.end(), {input, "--diagnosis", file("diagnosis.json"), "-o", file("report")});
        r.out = file("report.txt");
        break;
    }
    stages.push_back(std::move(r));
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  nlohmann::json seconds = nlohmann::json::object();
  const Stopwatch total;
  auto fail_with = [&](const std::string& stage, int code, const std::string& why) {
    const nlohmann::json failed = {{"stage", stage}, {"exit_code", code}, {"error", why}, {"attempt", attempt},
                                   {"host", host_name()}, {"seconds", seconds}};
    (void)write_file_atomically(file("failed.json"), failed.dump(1) + "\n", kSynced);
    fs::remove(file("running.json"), ec);
    std::fprintf(stderr, "driftlab: point %s: %s\n", point.id.c_str(), why.c_str());
    return g_stop ? kPointInterrupted : kPointFailed;
  };
  for (const auto& r : stages) {
    if (g_stop) return fail_with(r.name, kPointInterrupted, "interrupted before " + r.name);
    const std::string err = file((r.name + ".err").c_str());
    const Stopwatch stage;
    const pid_t pid = start_process(r.argv, r.out, err);
    if (pid < 0) return fail_with(r.name, 127, "cannot start " + exe);
    g_child = pid;
    if (g_stop) ::kill(pid, SIGTERM);
    const int code = wait_process(pid);
    g_child = 0;
    seconds[r.name] = stage.seconds();
    if (g_stop) return fail_with(r.name, code, "interrupted during " + r.name);
    if (code != 0) {
      const std::string why = last_line_of(err);
      return fail_with(r.name, code, "driftlab " + r.name + " exited with " + std::to_string(code) +
                                         (why.empty() ? "" : ": " + why));
    }
  }
  seconds["total"] = total.seconds();

  nlohmann::json metrics;
  try {
    metrics = point_metrics(plan, d.string());
  } catch (const nlohmann::json::exception& e) {
    return fail_with("collect", 1, std::string("reading the stages' JSON: ") + e.what());
  }
  if (!s.keep_logs) {
    fs::remove(file("sim.lcm"), ec);
    fs::remove(file("replay.lcm"), ec);
  }
  const nlohmann::json result = {{"id", point.id}, {"params", params}, {"metrics", metrics}, {"seconds", seconds},
                                 {"attempt", attempt}, {"host", host_name()}};
  // The done-marker, last: a point with result.json is whole and never runs again.
  if (Status st = write_file_atomically(file("result.json"), result.dump(1) + "\n", kSynced); !st) {
    return fail_with("collect", 1, st.message());
  }
  fs::remove(file("running.json"), ec);
  fs::remove(file("failed.json"), ec);
  return kPointDone;
}

}  // namespace driftlab::batch
