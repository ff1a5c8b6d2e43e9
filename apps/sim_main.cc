// driftlab sim: simulate a robot in a Bullet world from a scenario and write every stream to an LCM log, with
// ground truth and the injected faults.
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/config.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "core/text_file.h"
#include "core/wall_clock.h"
#include "runtime/live_publisher.h"
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
  if (a.duration > 0) scenario->duration = a.duration;
  if (a.seed >= 0) {
    scenario->seed = static_cast<uint64_t>(a.seed);
    scenario->faults.seed = static_cast<uint64_t>(a.seed);
  }
  if (!a.faults.empty()) {
    auto text = read_text_file(a.faults, "fault description");
    if (!text) return fail(text.error().message);
    auto faults = parse_faults(*text, a.faults);
    if (!faults) return fail(faults.error().message);
    scenario->faults_path = a.faults;
    scenario->faults_text = *text;
    const bool own_seed = faults->seed != 0;
    scenario->faults = std::move(*faults);
    if (!own_seed) scenario->faults.seed = scenario->seed;
  }
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
  const auto& r = *report;
  int64_t total = 0;
  for (const auto& [channel, n] : r.messages) total += n;
  if (a.json.wanted()) {
    nlohmann::json j;
    j["log"] = a.out;
    j["faults"] = r.faults_json;
    j["scenario"] = path;
    j["simulated_s"] = r.simulated_s;
    j["wall_s"] = wall;
    j["real_time_factor"] = wall > 0 ? r.simulated_s / wall : 0;
    j["interrupted"] = r.interrupted;
    j["messages"] = r.messages;
    j["distance_m"] = r.distance_m;
    j["laps"] = r.laps;
    j["odometry_error_m"] = r.odometry_error_m;
    j["notes"] = r.notes;
    if (!a.json.emit(j.dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::printf("%s %.1f s of %s in %.2f s (%.0fx real time): %s messages to %s\n",
              r.interrupted ? "interrupted after" : "simulated", r.simulated_s, scenario->name.c_str(), wall,
              wall > 0 ? r.simulated_s / wall : 0.0, thousands(total).c_str(), a.out.c_str());
  for (const auto& [channel, n] : r.messages) std::printf("  %-20s %s\n", channel.c_str(), thousands(n).c_str());
  if (!scenario->drone.enabled) {
    std::printf("drove %.1f m (%zu laps); odometry is %.2f m off the truth at the end\n", r.distance_m, r.laps,
                r.odometry_error_m);
  }
  for (const std::string& note : r.notes) std::printf("%s\n", note.c_str());
  std::printf("injected faults: %s\n", r.faults_json.c_str());
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
