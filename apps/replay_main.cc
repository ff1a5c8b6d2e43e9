// driftlab replay: re-feed logs, deterministically, to SLAM, the estimator and the controller on a virtual clock;
// correct clocks or inject faults first, write what the modules publish, re-publish on LCM.
#include <CLI/CLI.hpp>
#include <signal.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "analyzers/timing.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "controller/controller_module.h"
#include "estimator/estimator_module.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "lcmtypes/type_registry.h"
#include "replayer/live_runner.h"
#include "replayer/replayer.h"
#include "slam/slam_module.h"
#include "sim/scenario.h"

namespace driftlab::apps {
namespace {

struct ReplayArgs {
  std::vector<std::string> logs;
  std::string modules;
  std::string config;
  std::string out;
  double rate = 1.0;
  bool fast = false;
  double start = 0, end = 0;
  std::string channels;
  std::vector<std::string> remap;
  std::string order = "received";
  double reorder_window = 0.5;
  std::string restamp;
  std::string inject;
  std::string publish;
  bool timing = false;
  bool no_inputs = false;
  bool json = false;
};

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

constexpr std::array<const char*, 3> kModules = {"slam", "estimator", "controller"};

std::string known_modules() {
  std::string s;
  for (const char* m : kModules) s += (s.empty() ? "" : ", ") + std::string(m);
  return s;
}

/// The controller's defaults from a simulator scenario: its route, start pose and follower settings.
Result<controller::ControllerConfig> controller_base(const std::string& scenario_path) {
  auto sc = sim::load_scenario(scenario_path);
  if (!sc) return sc.error();
  controller::ControllerConfig c;
  c.route = sc->route;
  c.start = {sc->start.x(), sc->start.y(), sc->start.z()};
  c.pursuit = sc->controller.pursuit;
  c.rate = sc->controller.rate;
  c.footprint_radius = sc->controller.footprint_radius;
  c.logged_channel = sc->controller.channel;
  return c;
}

Result<std::unique_ptr<Module>> make_module(const std::string& name, const YAML::Node& config,
                                            const std::string& origin, const std::string& config_dir,
                                            const slam::HasData& has_data, std::vector<std::string>& notes) {
  if (name == "estimator") return estimator::make_estimator(config, origin);
  if (name == "slam") {
    std::string backend;
    auto m = slam::make_slam(config, origin, has_data, &backend);
    if (m) notes.push_back("slam: " + backend + " backend");
    return m;
  }
  if (name == "controller") {
    std::string scenario;
    if (config.IsMap() && config["scenario"].IsDefined()) {
      scenario = config["scenario"].as<std::string>();
      if (!scenario.empty() && scenario[0] != '/') scenario = (std::filesystem::path(config_dir) / scenario).string();
    } else if (!(config.IsMap() && config["route"].IsDefined())) {
      scenario = sim::default_scenario_path();
      notes.push_back("controller: route, start and settings from the default scenario " + scenario);
    }
    controller::ControllerConfig base;
    if (!scenario.empty()) {
      auto b = controller_base(scenario);
      if (!b) return b.error();
      base = std::move(*b);
    }
    return controller::make_controller(config, origin, std::move(base));
  }
  return Error{"--modules: unknown module '" + name + "' (known: " + known_modules() + ")"};
}

/// Clock corrections from the timing diagnosis: channels whose stamps run ahead of their arrival (a clock that is
/// ahead, which no transport can explain) or whose clock drifts.
Result<replay::Restamp> restamp_from_diagnosis(const std::vector<std::string>& logs, std::vector<std::string>& notes) {
  replay::Restamp r;
  for (const auto& log : logs) {
    auto d = analyzers::diagnose(log);
    if (!d) return d.error();
    for (const auto& c : d->channels) {
      if (!c.clock_valid) continue;
      const bool ahead = c.clock_offset_s > 0.001;
      const bool drifts = std::abs(c.clock_drift_ppm) >= 25;
      if (!ahead && !drifts) continue;
      r[c.name] = {ahead ? c.clock_offset_s : 0.0, drifts ? c.clock_drift_ppm : 0.0, d->start_utime};
      char buf[200];
      std::snprintf(buf, sizeof(buf), "restamp %s: %+.1f ms, %+.0f ppm (from the timing diagnosis of %s)",
                    c.name.c_str(), r[c.name].offset_s * 1e3, r[c.name].drift_ppm, log.c_str());
      notes.push_back(buf);
    }
  }
  return r;
}

/// The modules named in `list` (comma-separated), with their settings from the config file (one map per module
/// name). Errors are one line naming the file, line and key.
Result<std::vector<std::unique_ptr<Module>>> load_modules(const std::string& list, const std::string& config_path,
                                                          const slam::HasData& has_data,
                                                          std::vector<std::string>& notes) {
  YAML::Node config;
  std::string config_dir = ".";
  if (!config_path.empty()) {
    std::ifstream in(config_path);
    if (!in) return Error{config_path + ": cannot open the module config"};
    std::stringstream text;
    text << in.rdbuf();
    try {
      config = YAML::Load(text.str());
    } catch (const YAML::Exception& e) {
      return Error{config_path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
    }
    if (!config.IsNull() && !config.IsMap()) return Error{config_path + ":1: expected a map of module name: settings"};
    config_dir = std::filesystem::path(config_path).parent_path().string();
    if (config_dir.empty()) config_dir = ".";
  }
  if (config.IsMap()) {
    for (const auto& kv : config) {
      const std::string key = kv.first.as<std::string>();
      if (std::find_if(kModules.begin(), kModules.end(), [&](const char* m) { return key == m; }) == kModules.end()) {
        return Error{config_path + ":" + std::to_string(kv.first.Mark().line + 1) + ": unknown module '" + key +
                     "' (known: " + known_modules() + ")"};
      }
    }
  }
  std::vector<std::unique_ptr<Module>> modules;
  std::stringstream names(list);
  for (std::string name; std::getline(names, name, ',');) {
    if (name.empty()) continue;
    const YAML::Node node = config.IsMap() ? config[name] : YAML::Node();
    auto m = make_module(name, node, config_path.empty() ? "--config" : config_path, config_dir, has_data, notes);
    if (!m) return m.error();
    modules.push_back(std::move(*m));
  }
  return modules;
}

nlohmann::json modules_json(const std::vector<replay::ModuleReport>& reports) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& m : reports) {
    out.push_back({{"name", m.name},
                   {"inputs", m.inputs},
                   {"late", m.late},
                   {"out_of_order", m.out_of_order},
                   {"dropped", m.dropped},
                   {"outputs", m.outputs},
                   {"proc_mean_s", m.proc_mean_s},
                   {"proc_p95_s", m.proc_p95_s},
                   {"proc_max_s", m.proc_max_s},
                   {"queue_depth_max", m.queue_depth_max},
                   {"warnings", m.warnings},
                   {"metrics", nlohmann::json(std::map<std::string, double>(m.metrics.begin(), m.metrics.end()))}});
  }
  return out;
}

void print_modules(const std::vector<replay::ModuleReport>& reports, bool timing) {
  for (const auto& m : reports) {
    std::printf("  %-10s %s inputs (%s late, %s out of order, %s dropped), %s outputs", m.name.c_str(),
                thousands(m.inputs).c_str(), thousands(m.late).c_str(), thousands(m.out_of_order).c_str(),
                thousands(m.dropped).c_str(), thousands(m.outputs).c_str());
    if (timing) {
      std::printf(", %.3f ms per input (p95 %.3f ms), queue <= %d", m.proc_mean_s * 1e3, m.proc_p95_s * 1e3,
                  m.queue_depth_max);
    }
    std::printf("\n");
    if (!m.metrics.empty()) {
      std::printf("            ");
      for (size_t i = 0; i < m.metrics.size(); ++i) {
        const double v = m.metrics[i].second;
        const bool whole = v == std::floor(v) && std::abs(v) < 1e15;
        std::printf(whole ? "%s%s %.0f" : "%s%s %.4g", i > 0 ? ", " : "", m.metrics[i].first.c_str(), v);
      }
      std::printf("\n");
    }
    for (const auto& w : m.warnings) std::printf("  warning: %s\n", w.c_str());
  }
}

int run_replay(const ReplayArgs& a) {
  replay::ReplayOptions o;
  o.logs = a.logs;
  o.channels = a.channels;
  o.out = a.out;
  o.timing = a.timing;
  o.write_inputs = !a.no_inputs;
  o.order = a.order == "stamp" ? replay::Order::kStamp : replay::Order::kReceived;
  o.reorder_window_s = a.reorder_window;
  o.start_s = a.start;
  if (a.end > 0) o.end_s = a.end;
  for (const auto& m : a.remap) {
    const auto eq = m.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == m.size()) {
      return fail("--remap " + m + ": expected FROM=TO (channel names)");
    }
    o.remap.emplace_back(m.substr(0, eq), m.substr(eq + 1));
  }
  for (const auto& log : a.logs) {
    if (!std::filesystem::is_regular_file(log)) return fail(log + ": no such log file");
  }
  try {
    std::regex check(a.channels);
  } catch (const std::regex_error& e) {
    return fail("invalid channel regex '" + a.channels + "': " + e.what());
  }
  std::vector<std::string> notes;
  if (a.restamp == "auto") {
    auto r = restamp_from_diagnosis(a.logs, notes);
    if (!r) return fail(r.error().message);
    o.restamp = std::move(*r);
  } else if (!a.restamp.empty()) {
    auto r = replay::load_restamp(a.restamp);
    if (!r) return fail(r.error().message);
    o.restamp = std::move(*r);
  }
  if (!a.inject.empty()) {
    auto f = load_faults(a.inject);
    if (!f) return fail(f.error().message);
    o.inject = std::move(*f);
  }

  // Whether the logs hold a message type on a channel (the slam module's `auto` backend asks): the channel's first
  // message tells.
  const slam::HasData has_data = [&a](const std::string& channel, const std::string& type) {
    if (!a.channels.empty() && !std::regex_match(channel, std::regex(a.channels))) return false;  // filtered out
    static const std::regex special(R"([.^$|()\[\]{}*+?\\])");
    for (const auto& log : a.logs) {
      auto r = LogReader::open(log, {.channels = std::regex_replace(channel, special, R"(\$&)")});
      Event e;
      if (r && r->next(e)) {
        const char* name = lcmtypes::type_name(logfmt::fingerprint(e.data));
        if (name != nullptr && type == name) return true;
      }
    }
    return false;
  };
  auto modules = load_modules(a.modules, a.config, has_data, notes);
  if (!modules) return fail(modules.error().message);
  replay::Replayer replayer(o);
  for (auto& m : *modules) replayer.add_module(std::move(m));

  std::unique_ptr<LivePublisher> live;
  if (!a.publish.empty()) {
    auto p = LivePublisher::open(a.publish, a.fast ? 0.0 : a.rate, "--publish");
    if (!p) return fail(p.error().message);
    live = std::move(*p);
  }
  replay::Sink sink;
  if (live) sink = [&live](const BusMessage& m) { live->publish(m.channel, m.utime, m.data); };

  if (Status s = replayer.open(); !s) return fail(s.message());
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGXFSZ, SIG_IGN);
  const auto t0 = std::chrono::steady_clock::now();
  auto report = replayer.run(sink, &g_stop);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!report) return fail(report.error().message, kExitFailure);
  const auto& r = *report;
  const double span = static_cast<double>(r.end_utime - r.start_utime) * 1e-6;

  if (a.json) {
    nlohmann::json j;
    j["logs"] = a.logs;
    j["out"] = a.out;
    j["read"] = r.read;
    j["dispatched"] = r.dispatched;
    j["outputs"] = r.outputs;
    j["replayed_s"] = span;
    j["wall_s"] = wall;
    j["real_time_factor"] = wall > 0 ? span / wall : 0;
    j["interrupted"] = r.interrupted;
    j["log_problems"] = r.log_problems;
    j["channels"] = r.channels;
    j["notes"] = notes;
    j["restamp"] = nlohmann::json::object();
    for (const auto& [channel, c] : o.restamp) {
      j["restamp"][channel] = {{"offset_s", c.offset_s}, {"drift_ppm", c.drift_ppm}};
    }
    j["modules"] = modules_json(r.modules);
    j["injected_faults"] = r.injected.size();
    std::printf("%s\n", j.dump(2).c_str());
    return kExitOk;
  }
  for (const auto& n : notes) std::printf("%s\n", n.c_str());
  std::printf("%s %.1f s of log in %.2f s (%.0fx real time): %s events in, %s module outputs%s%s\n",
              r.interrupted ? "interrupted after" : "replayed", span, wall, wall > 0 ? span / wall : 0.0,
              thousands(r.dispatched).c_str(), thousands(r.outputs).c_str(), a.out.empty() ? "" : " -> ",
              a.out.c_str());
  if (r.log_problems > 0) std::printf("  %llu problems in the logs (see driftlab info)\n",
                                      static_cast<unsigned long long>(r.log_problems));
  if (!r.injected.empty()) std::printf("  injected %zu faults (manifest on %s)\n", r.injected.size(),
                                       o.faults_channel.c_str());
  print_modules(r.modules, a.timing);
  return kExitOk;
}

struct RunArgs {
  std::string modules, config, url, out;
  double duration = 0;
  bool json = false;
};

int run_live(const RunArgs& a) {
  std::vector<std::string> notes;
  auto modules = load_modules(a.modules, a.config, [](const std::string&, const std::string&) { return false; }, notes);
  if (!modules) return fail(modules.error().message);
  if (modules->empty()) return fail("--modules: name at least one module (" + known_modules() + ")");
  replay::LiveRunner runner({.url = a.url, .out = a.out, .duration_s = a.duration});
  for (auto& m : *modules) runner.add_module(std::move(m));
  if (Status s = runner.open(); !s) return fail(s.message());
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGXFSZ, SIG_IGN);
  auto report = runner.run(&g_stop);
  if (!report) return fail(report.error().message, kExitFailure);
  if (a.json) {
    nlohmann::json j;
    j["url"] = a.url;
    j["out"] = a.out;
    j["received"] = report->received;
    j["outputs"] = report->outputs;
    j["wall_s"] = report->wall_s;
    j["notes"] = notes;
    j["modules"] = modules_json(report->modules);
    std::printf("%s\n", j.dump(2).c_str());
    return kExitOk;
  }
  for (const auto& n : notes) std::printf("%s\n", n.c_str());
  std::printf("ran %.1f s on %s: %s messages handled, %s module outputs%s%s\n", report->wall_s, a.url.c_str(),
              thousands(report->received).c_str(), thousands(report->outputs).c_str(), a.out.empty() ? "" : " -> ",
              a.out.c_str());
  print_modules(report->modules, true);
  return kExitOk;
}

}  // namespace

void add_run_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "Run SLAM, the estimator and the controller live, on an LCM bus.");
  cmd->footer(
      "The same modules as `driftlab replay`, behind the same Bus, with the wall clock as their clock: they\n"
      "subscribe on the LCM URL and publish there. OUT gets what they published and their statistics\n"
      "(MODULE_STATS, every second, with processing times); record the inputs with `driftlab record`. Ctrl-C or\n"
      "--duration stops, finishes the modules (maps are written) and closes a valid log.");
  cmd->add_option("--modules", a->modules, "Modules to run, comma-separated (" + known_modules() + ")")->required();
  cmd->add_option("--config", a->config, "Module settings (YAML: one map per module name)");
  cmd->add_option("--url", a->url, "LCM URL")->required();
  cmd->add_option("-o,--out", a->out, "Log of the module outputs and statistics");
  cmd->add_option("--duration", a->duration, "Stop after this many seconds (0: at Ctrl-C)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", a->json, "Print a JSON summary instead of text");
  cmd->callback([a, exit_code] { *exit_code = run_live(*a); });
}

void add_replay_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand(
      "replay", "Replay logs through SLAM, the estimator and the controller on a virtual clock, deterministically.");
  cmd->footer(
      "Merges the logs in time order and dispatches every event to the modules through the Bus they use live;\n"
      "what they publish goes to the other modules and to OUT with per-module statistics (MODULE_STATS). The same\n"
      "inputs and options give a byte-identical OUT (unless --timing). --restamp corrects clocks before dispatch\n"
      "(FILE: `channels: {CH: {offset_s, drift_ppm}}`; auto: from the timing diagnosis); --inject adds faults\n"
      "(the simulator's fault description, docs/faults.md). Module settings: docs/replay.md.");
  cmd->add_option("logs", a->logs, "Logs to replay")->required();
  cmd->add_option("--modules", a->modules, "Modules to run, comma-separated (" + known_modules() + ")");
  cmd->add_option("--config", a->config, "Module settings (YAML: one map per module name)");
  cmd->add_option("-o,--out", a->out, "Output log: the inputs as dispatched, the module outputs and statistics");
  cmd->add_option("--rate", a->rate, "With --publish: pace at this multiple of real time")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--fast", a->fast, "With --publish: as fast as possible");
  cmd->add_option("--start", a->start, "Skip this many seconds from the start of the logs")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--end", a->end, "Stop this many seconds after the start of the logs (0: at the end)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("-c,--channels", a->channels, "Only channels fully matching this regex (ECMAScript)");
  cmd->add_option("--remap", a->remap, "Deliver channel FROM as TO (FROM=TO, repeatable)");
  cmd->add_option("--order", a->order, "Dispatch order: received (log time) or stamp (header stamps)")
      ->capture_default_str()
      ->check(CLI::IsMember({"received", "stamp"}));
  cmd->add_option("--reorder-window", a->reorder_window, "With --order stamp: wait this long for stragglers [s]")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--restamp", a->restamp, "Clock corrections before dispatch: FILE or auto");
  cmd->add_option("--inject", a->inject, "Faults to add before dispatch (YAML, as the simulator's --faults)");
  cmd->add_option("--publish", a->publish, "Re-publish inputs and outputs on this LCM URL, paced by --rate");
  cmd->add_flag("--timing", a->timing, "Measure processing time per input and the queues it implies");
  cmd->add_flag("--no-inputs", a->no_inputs, "Write only the module outputs and statistics to OUT");
  cmd->add_flag("--json", a->json, "Print a JSON summary instead of text");
  cmd->callback([a, exit_code] { *exit_code = run_replay(*a); });
}

}  // namespace driftlab::apps
