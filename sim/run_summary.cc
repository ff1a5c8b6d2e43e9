#include "sim/run_summary.h"

#include "core/number_text.h"

namespace driftlab::sim {
namespace {

int64_t total_messages(const SimReport& r) {
  int64_t total = 0;
  for (const auto& [channel, n] : r.messages) total += n;
  return total;
}

}  // namespace

nlohmann::json to_json(const SimRun& run) {
  const SimReport& r = run.report;
  nlohmann::json j;
  j["log"] = run.out;
  j["faults"] = r.faults_json;
  j["scenario"] = run.scenario_path;
  j["simulated_s"] = r.simulated_s;
  j["wall_s"] = run.wall_s;
  j["real_time_factor"] = run.wall_s > 0 ? r.simulated_s / run.wall_s : 0;
  j["interrupted"] = r.interrupted;
  j["messages"] = r.messages;
  j["distance_m"] = r.distance_m;
  j["laps"] = r.laps;
  j["odometry_error_m"] = r.odometry_error_m;
  j["notes"] = r.notes;
  return j;
}

std::string sim_run_text(const SimRun& run) {
  const SimReport& r = run.report;
  std::string out;
  appendf(out, "%s %.1f s of %s in %.2f s (%.0fx real time): %s messages to %s\n",
          r.interrupted ? "interrupted after" : "simulated", r.simulated_s, run.scenario_name.c_str(), run.wall_s,
          run.wall_s > 0 ? r.simulated_s / run.wall_s : 0.0, thousands(total_messages(r)).c_str(), run.out.c_str());
  for (const auto& [channel, n] : r.messages) appendf(out, "  %-20s %s\n", channel.c_str(), thousands(n).c_str());
  if (run.ground_robot) {
    appendf(out, "drove %.1f m (%zu laps); odometry is %.2f m off the truth at the end\n", r.distance_m, r.laps,
            r.odometry_error_m);
  }
  for (const std::string& note : r.notes) out += note + "\n";
  return out + "injected faults: " + r.faults_json + "\n";
}

nlohmann::json to_json(const ClosedLoopRun& closed) {
  const SimReport& r = closed.run.report;
  nlohmann::json j;
  j["log"] = closed.log;
  j["out"] = closed.run.out;
  j["scenario"] = closed.run.scenario_path;
  j["simulated_s"] = r.simulated_s;
  j["wall_s"] = closed.run.wall_s;
  j["notes"] = closed.notes;
  j["restamp"] = nlohmann::json::object();
  for (const auto& [channel, k] : closed.corrections.clocks) {
    j["restamp"][channel] = {{"offset_s", k.offset_s}, {"drift_ppm", k.drift_ppm}};
  }
  j["retime"] = nlohmann::json::object();
  for (const auto& [channel, d] : closed.corrections.retime) j["retime"][channel] = d.seconds();
  j["messages"] = r.messages;
  j["run"] = r.notes;
  return j;
}

std::string closed_loop_text(const ClosedLoopRun& closed) {
  const SimReport& r = closed.run.report;
  std::string out;
  for (const auto& n : closed.notes) out += n + "\n";
  if (closed.corrections.clocks.empty() && closed.corrections.retime.empty()) {
    out += "no corrections: the run is the log's simulation again\n";
  }
  appendf(out, "%s %.1f s of %s in closed loop in %.2f s: %s messages -> %s\n",
          r.interrupted ? "interrupted after" : "ran", r.simulated_s, closed.run.scenario_name.c_str(),
          closed.run.wall_s, thousands(total_messages(r)).c_str(), closed.run.out.c_str());
  for (const auto& n : r.notes) out += n + "\n";
  return out;
}

}  // namespace driftlab::sim
