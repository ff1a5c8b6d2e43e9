// driftlab sim: simulate a robot in a Bullet world from a scenario and write every stream to an LCM log, with
// ground truth and the injected faults.
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>
#include <thread>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/config.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "core/wall_clock.h"
#include "runtime/live_publisher.h"
#include "sim/run_summary.h"
#include "sim/scenario.h"
#include "sim/simulator.h"
#include "sim/world.h"

namespace driftlab::apps {
namespace {

struct SimArgs {
  std::string scenario;
  std::string out = "sim.lcm";
  double duration = 0;
  int64_t seed = -1;
  std::string faults;
  std::string live_url;
  double live_rate = 1.0;
  std::string rays = "grid";
  JsonOutput json;
};

/// --help-config: the keys of a scenario, its world and a fault description, from the tables they are read with.
void print_config_help() {
  std::printf(
      "## Scenario: `driftlab sim SCENARIO`\n\n%s\n"
      "## World file: a scenario's `world:`\n\n%s\n"
      "## Fault description: `driftlab sim --faults FILE`, a scenario's `faults:`, `driftlab replay --inject "
      "FILE`\n\n%s",
      sim::scenario_reference().c_str(), sim::world_reference().c_str(), fault_config_table().reference().c_str());
}

int run_sim(const SimArgs& a) {
  const std::string path = a.scenario.empty() ? sim::default_scenario_path() : a.scenario;
  // The log and the fault manifest beside it are both outputs: neither may be the scenario or --json-out.
  const std::string manifest = a.out.empty() ? std::string() : sim::faults_json_path(a.out);
  for (const std::string& out : {a.out, manifest}) {
    if (Status s = refuse_same_file(out, {path}); !s) return fail(s.message());
  }
  if (Status s = a.json.check({path}, {a.out, manifest}); !s) return fail(s.message());
  auto scenario = sim::load_scenario(path);
  if (!scenario) return fail(scenario.error().message);
  if (Status st = sim::apply_overrides(*scenario, {a.duration, a.seed, a.faults}); !st) return fail(st.message());
  auto simulation = sim::Simulation::create(*scenario, a.rays == "bullet" ? sim::RayBackend::kBullet : sim::RayBackend::kGrid);
  if (!simulation) return fail(simulation.error().message);

  std::unique_ptr<runtime::LivePublisher> live;
  if (!a.live_url.empty()) {
    auto p = runtime::LivePublisher::open(a.live_url, a.live_rate, "--live");
    if (!p) return fail(p.error().message);
    live = std::move(*p);
  }
  sim::SimOptions o;
  o.out = a.out;
  o.version = DRIFTLAB_VERSION;
  o.stop = stop_on_signals();
  if (live) {
    o.on_message = [&live](const std::string& c, int64_t t, std::span<const uint8_t> b) {
      live->publish(c, Time::from_us(t), b);
    };
  }
  Progress progress("simulating", Progress::Unit::kMilliseconds);
  o.progress = [&progress](double done, double total) {
    progress.update(static_cast<uint64_t>(done * 1000), static_cast<uint64_t>(total * 1000));
  };
  const Stopwatch running;
  auto report = (*simulation)->run(o);
  const double wall = running.seconds();
  progress.finish();
  if (!report) return fail(report.error().message, kExitFailure);
  const sim::SimRun run{path, scenario->name, !scenario->drone.enabled, a.out, std::move(*report), wall};
  if (a.json.wanted()) {
    if (!a.json.emit(to_json(run).dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::fputs(sim::sim_run_text(run).c_str(), stdout);
  return kExitOk;
}

}  // namespace

void add_sim_command(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<SimArgs>();
  CLI::App* cmd = app.add_subcommand("sim", tool_description("sim"));
  cmd->footer(
      "Without SCENARIO, runs the default indoor scenario (sim/scenarios/indoor.yaml; installed,\n"
      "PREFIX/share/driftlab/scenarios/indoor.yaml). The same scenario and seed give a byte-identical log. The log\n"
      "is written as OUT.partial and renamed when complete; Ctrl-C stops the run and closes a valid log of what was\n"
      "simulated. The injected faults go to the FAULTS channel and to OUT.faults.json. Scenario format:\n"
      "docs/simulator.md; faults: docs/faults.md.");
  cmd->add_option("scenario", a->scenario, "Scenario file (YAML)");
  cmd->add_option("-o,--out", a->out, "Log to write")->capture_default_str();
  cmd->add_option("--duration", a->duration, "Simulated seconds (default: the scenario's)")
      ->check(in_range(kSimDuration, "s"));
  cmd->add_option("--seed", a->seed, "Random seed (default: the scenario's)")->check(in_range(kSeed));
  cmd->add_option("--faults", a->faults, "Fault description (YAML) replacing the scenario's faults");
  add_config_help(*cmd, print_config_help);
  cmd->add_option("--live", a->live_url, "Also publish every message on this LCM URL as it arrives");
  cmd->add_option("--live-rate", a->live_rate, "Pace --live at this multiple of real time (0: as fast as possible)")
      ->capture_default_str()
      ->check(in_range(config::between(0, kPaceRate.max)));
  cmd->add_option("--rays", a->rays, "Ray casting: grid (fast, exact for the world's shapes) or bullet (Bullet's ray test)")
      ->capture_default_str()
      ->check(CLI::IsMember({"grid", "bullet"}));
  add_json_options(cmd, &a->json, "a summary");
  cmd->callback([a, exit_code] { *exit_code = run_sim(*a); });
}

}  // namespace driftlab::apps
