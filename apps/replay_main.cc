// driftlab replay: re-feed logs, deterministically, to SLAM, the estimator and the controller on a virtual clock;
// correct clocks or inject faults first, write what the modules publish, re-publish on LCM.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>

#include "analyzers/clock_corrections.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/config.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "core/time.h"
#include "core/wall_clock.h"
#include "modules/registry.h"
#include "recordings/log_input.h"
#include "replayer/replay_summary.h"
#include "replayer/replayer.h"
#include "runtime/live_publisher.h"
#include "runtime/live_runner.h"
#include "runtime/module_report.h"
#include "sim/run_summary.h"
#include "sim/simulator.h"

namespace driftlab::apps {
namespace {

struct ReplayArgs {
  replay::ReplayOptions o;  ///< logs, channels, out, order, reorder_window_s, start_s, timing: as given
  std::string modules;
  std::string config;
  double rate = 1.0;
  bool fast = false;
  double end = 0;
  std::vector<std::string> remap;
  std::string restamp;
  std::vector<std::string> retime;
  bool closed_loop = false;
  std::string inject;
  std::string publish;
  bool no_inputs = false;
  JsonOutput json;
};

/// --help-config: the keys of the files replay and run read, from the tables they are read with.
void print_config_help() {
  std::printf("## Module settings: `driftlab replay|run --config FILE`\n\n"
              "One map per module name (%s), each optional; an absent key keeps its default. What the modules do: "
              "docs/replay.md.\n\n%s\n"
              "## Restamp file: `driftlab replay --restamp FILE`\n\n%s\n"
              "The fault description of `driftlab replay --inject FILE` is the simulator's (`driftlab sim "
              "--help-config`).\n",
              modules::known_modules().c_str(), modules::config_reference().c_str(),
              replay::restamp_file_table().reference().c_str());
}

/// --closed-loop: the simulation that made the log, run again with the corrections applied where its messages are
/// received on board. A log has no physics to re-run open loop: a drone or an arm moves as its controllers, fed
/// by what they receive, make it move.
int run_closed_loop(const ReplayArgs& a, const ReplayArgs& defaults) {
  if (a.o.logs.size() != 1) return fail("--closed-loop: give one log, the one the simulation wrote");
  if (a.o.out.empty()) return fail("--closed-loop: give -o OUT for the log of the new run");
  const std::pair<const char*, bool> unused[] = {{"--modules", !a.modules.empty()},
                                                 {"--config", !a.config.empty()},
                                                 {"--inject", !a.inject.empty()},
                                                 {"--channels", !a.o.channels.empty()},
                                                 {"--remap", !a.remap.empty()},
                                                 {"--order", a.o.order != defaults.o.order},
                                                 {"--start", a.o.start_s != defaults.o.start_s},
                                                 {"--end", a.end != defaults.end},
                                                 {"--publish", !a.publish.empty()},
                                                 {"--no-inputs", a.no_inputs},
                                                 {"--timing", a.o.timing}};
  for (const auto& [option, given] : unused) {
    if (given) {
      return fail(std::string("--closed-loop runs the simulation's own modules on board: ") + option +
                  " does not apply");
    }
  }
  if (Status s = refuse_same_file(a.o.out, a.o.logs); !s) return fail(s.message());
  if (Status s = a.json.check(a.o.logs, {a.o.out}); !s) return fail(s.message());
  const std::string& log = a.o.logs[0];
  auto scenario = sim::scenario_of_log(log);
  if (!scenario) return fail(scenario.error().message);
  sim::ReceiveCorrections corrections;
  if (!a.restamp.empty() && a.restamp != "auto") {
    auto r = replay::load_restamp(a.restamp);
    if (!r) return fail(r.error().message);
    corrections.clocks = std::move(*r);
  }
  auto plan = analyzers::plan_corrections({log}, a.restamp == "auto", a.retime);
  if (!plan) return fail(plan.error().message);
  if (a.restamp == "auto") corrections.clocks = std::move(plan->clocks);
  corrections.retime = std::move(plan->retime);
  std::vector<std::string> notes = std::move(plan->notes);
  auto simulation = sim::Simulation::create(*scenario);
  if (!simulation) return fail(simulation.error().message);
  for (const std::string& channel : (*simulation)->recomputed_channels()) {
    if (corrections.clocks.erase(channel) > 0) {
      notes.push_back("not restamping " + channel + " on board: the run makes it again from its inputs");
    }
  }
  sim::SimOptions o;
  o.out = a.o.out;
  o.version = DRIFTLAB_VERSION;
  o.corrections = corrections;
  o.stop = stop_on_signals();
  const Stopwatch running;
  auto report = (*simulation)->run(o);
  const double wall = running.seconds();
  if (!report) return fail(report.error().message, kExitFailure);
  const sim::ClosedLoopRun run{
      log,
      {scenario->path, scenario->name, !scenario->drone.enabled, a.o.out, std::move(*report), wall},
      corrections,
      notes};
  if (a.json.wanted()) {
    if (!a.json.emit(to_json(run).dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::fputs(sim::closed_loop_text(run).c_str(), stdout);
  return kExitOk;
}

int run_replay(ReplayArgs a) {
  if (a.closed_loop) return run_closed_loop(a, ReplayArgs{});
  if (!a.retime.empty()) return fail("--retime applies to --closed-loop (commands re-timed as the arm receives them)");
  if (Status s = refuse_same_file(a.o.out, a.o.logs); !s) return fail(s.message());  // the recordings given
  if (Status s = a.json.check(a.o.logs, {a.o.out}); !s) return fail(s.message());
  for (auto& log : a.o.logs) {
    auto converted = recordings::event_log_for(log);  // another tool's recording: its cached conversion
    if (!converted) return fail(converted.error().message, exit_code_for(converted.error()));
    log = *converted;
  }
  replay::ReplayOptions o = a.o;
  o.write_inputs = !a.no_inputs;
  if (a.end > 0) o.end_s = a.end;
  for (const auto& m : a.remap) {
    auto r = replay::parse_remap(m);
    if (!r) return fail(r.error().message);
    o.remap.push_back(std::move(*r));
  }
  if (Status s = refuse_same_file(a.o.out, a.o.logs); !s) return fail(s.message());  // and their conversions
  if (Status s = a.json.check(a.o.logs, {a.o.out}); !s) return fail(s.message());
  if (a.end > 0 && a.end <= a.o.start_s) {
    return fail("--end " + short_number(a.end) + " must be after --start " + short_number(a.o.start_s) +
                " (both in seconds from the start of the logs)");
  }
  if (a.fast && a.rate != 1.0) std::fprintf(stderr, "driftlab: warning: --fast ignores --rate\n");
  try {
    std::regex check(a.o.channels);
  } catch (const std::regex_error& e) {
    return fail("invalid channel regex '" + a.o.channels + "': " + e.what());
  }
  std::vector<std::string> notes;
  if (a.restamp == "auto") {
    auto plan = analyzers::plan_corrections(a.o.logs, true, {});
    if (!plan) return fail(plan.error().message);
    o.restamp = std::move(plan->clocks);
    notes = std::move(plan->notes);
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
  if (!a.restamp.empty() && a.restamp != "auto") {
    std::vector<std::string> named;
    for (const auto& [channel, c] : o.restamp) named.push_back(channel);
    if (Status s = replay::refuse_absent_channels("--restamp " + a.restamp, named, a.o.logs); !s)
      return fail(s.message());
  }
  if (o.inject) {
    std::vector<std::string> named;
    for (const auto& [channel, f] : o.inject->streams) named.push_back(channel);
    if (Status s = replay::refuse_absent_channels("--inject " + a.inject, named, a.o.logs); !s)
      return fail(s.message());
  }

  // The slam module's `auto` backend and its unset input channels look at what the replay delivers (after the filter
  // and --remap); only when a module is asked for, as reading the logs' indexes may take a pass over them.
  const InputChannels inputs = a.modules.empty() ? InputChannels{} : replay::delivered_channels(o);
  auto modules = modules::load_modules(a.modules, a.config, inputs, notes);
  if (!modules) return fail(modules.error().message);
  Progress progress("replaying");
  o.progress = [&progress](uint64_t done, uint64_t total) { progress.update(done, total); };
  replay::Replayer replayer(o);
  for (auto& m : *modules) replayer.add_module(std::move(m));

  std::unique_ptr<runtime::LivePublisher> live;
  if (!a.publish.empty()) {
    auto p = runtime::LivePublisher::open(a.publish, a.fast ? 0.0 : a.rate, "--publish");
    if (!p) return fail(p.error().message);
    live = std::move(*p);
  }
  replay::Sink sink;
  if (live) sink = [&live](const BusMessage& m) { live->publish(m.channel, m.time, m.data); };

  if (Status s = replayer.open(); !s) return fail(s.message(), exit_code_for(s.error()));
  const Stopwatch running;
  auto report = replayer.run(sink, stop_on_signals());
  progress.finish();
  const double wall = running.seconds();
  if (!report) return fail(report.error().message, kExitFailure);
  if (report->read == 0 && a.o.start_s > 0) {
    return fail("--start " + short_number(a.o.start_s) + ": nothing to replay after it (past the end of the logs)");
  }
  const replay::ReplaySummary summary{a.o.logs, a.o.out, std::move(*report), wall, notes, o.restamp, o.faults_channel};
  if (a.json.wanted()) {
    if (!a.json.emit(to_json(summary).dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::fputs(replay::replay_text(summary, a.o.timing).c_str(), stdout);
  return kExitOk;
}

struct RunArgs {
  std::string modules, config;
  runtime::LiveOptions live;
  JsonOutput json;
};

int run_live(const RunArgs& a) {
  if (Status s = a.json.check({a.config}, {a.live.out}); !s) return fail(s.message());
  std::vector<std::string> notes;
  auto modules = modules::load_modules(a.modules, a.config, {}, notes);
  if (!modules) return fail(modules.error().message);
  if (modules->empty()) return fail("--modules: name at least one module (" + modules::known_modules() + ")");
  const SystemWallClock clock;
  runtime::LiveRunner runner(a.live, clock);
  for (auto& m : *modules) runner.add_module(std::move(m));
  if (Status s = runner.open(); !s) return fail(s.message(), exit_code_for(s.error()));
  auto report = runner.run(stop_on_signals());
  if (!report) return fail(report.error().message, kExitFailure);
  if (a.json.wanted()) {
    if (!a.json.emit(to_json(a.live, *report, notes).dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::fputs(runtime::live_text(a.live, *report, notes).c_str(), stdout);
  return kExitOk;
}

}  // namespace

void add_run_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", tool_description("run"));
  cmd->footer(
      "The same modules as `driftlab replay`, behind the same Bus, with the wall clock as their clock: they\n"
      "subscribe on the LCM URL and publish there. OUT gets what they published and their statistics\n"
      "(MODULE_STATS, every second, with processing times); record the inputs with `driftlab record`. Ctrl-C or\n"
      "--duration stops, finishes the modules (maps are written) and closes a valid log.");
  cmd->add_option("--modules", a->modules, "Modules to run, comma-separated (" + modules::known_modules() + ")")->required();
  cmd->add_option("--config", a->config, "Module settings (YAML: one map per module name)");
  add_config_help(*cmd, print_config_help);
  cmd->add_option("--url", a->live.url, "LCM URL")->required();
  cmd->add_option("-o,--out", a->live.out, "Log of the module outputs and statistics");
  cmd->add_option("--duration", a->live.duration_s, "Stop after this many seconds (0: at Ctrl-C)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e7), "s"));
  add_json_options(cmd, &a->json, "a summary");
  cmd->callback([a, exit_code] { *exit_code = run_live(*a); });
}

void add_replay_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand("replay", tool_description("replay"));
  cmd->footer(
      "Merges the logs in time order and dispatches every event to the modules through the Bus they use live;\n"
      "what they publish goes to the other modules and to OUT with per-module statistics (MODULE_STATS). The same\n"
      "inputs and options give a byte-identical OUT (unless --timing). --restamp corrects clocks before dispatch\n"
      "(FILE: `channels: {CH: {offset_s, drift_ppm}}`; auto: from the timing diagnosis); --inject adds faults\n"
      "(the simulator's fault description, docs/faults.md). Module settings: docs/replay.md. --closed-loop runs\n"
      "again the simulation that wrote the log (its scenario is in the log), the corrections applied where its\n"
      "modules receive their messages: a drone or an arm moves as its controllers make it, which no log can replay\n"
      "open loop.");
  cmd->add_option("logs", a->o.logs, "Logs to replay")->required();
  cmd->add_option("--modules", a->modules, "Modules to run, comma-separated (" + modules::known_modules() + ")");
  cmd->add_option("--config", a->config, "Module settings (YAML: one map per module name)");
  add_config_help(*cmd, print_config_help);
  cmd->add_option("-o,--out", a->o.out, "Output log: the inputs as dispatched, the module outputs and statistics");
  cmd->add_option("--rate", a->rate, "With --publish: pace at this multiple of real time")
      ->capture_default_str()
      ->check(in_range(kPaceRate));
  cmd->add_flag("--fast", a->fast, "With --publish: as fast as possible");
  cmd->add_option("--start", a->o.start_s, "Skip this many seconds from the start of the logs")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9), "s"));
  cmd->add_option("--end", a->end, "Stop this many seconds after the start of the logs (0: at the end)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9), "s"));
  cmd->add_option("-c,--channels", a->o.channels, "Only channels fully matching this regex (ECMAScript)");
  cmd->add_option("--remap", a->remap, "Deliver channel FROM as TO (FROM=TO, repeatable)");
  add_choice(cmd, "--order", &a->o.order, {replay::Order::kReceived, replay::Order::kStamp},
             "Dispatch order: received (log time) or stamp (header stamps)");
  cmd->add_option("--reorder-window", a->o.reorder_window_s, "With --order stamp: wait this long for stragglers [s]")
      ->capture_default_str()
      ->check(in_range(config::between(0, 3600), "s"));
  cmd->add_option("--restamp", a->restamp, "Clock corrections before dispatch: FILE or auto");
  cmd->add_flag("--closed-loop", a->closed_loop,
                "Run again the simulation that made the log (its modules on board, closed loop on the physics), with "
                "--restamp and --retime applied where its messages are received");
  cmd->add_option("--retime", a->retime,
                  "With --closed-loop: commands on CHANNEL start when they arrived less SECONDS, on a controller that "
                  "honours stamps (CHANNEL=SECONDS, or auto: the command-to-motion delay diagnose measures)");
  cmd->add_option("--inject", a->inject, "Faults to add before dispatch (YAML, as the simulator's --faults)");
  cmd->add_option("--publish", a->publish, "Re-publish inputs and outputs on this LCM URL, paced by --rate");
  cmd->add_flag("--timing", a->o.timing, "Measure processing time per input and the queues it implies");
  cmd->add_flag("--no-inputs", a->no_inputs, "Write only the module outputs and statistics to OUT");
  add_json_options(cmd, &a->json, "a summary");
  cmd->callback([a, exit_code] { *exit_code = run_replay(*a); });
}

}  // namespace driftlab::apps
