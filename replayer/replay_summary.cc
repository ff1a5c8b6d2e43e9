#include "replayer/replay_summary.h"

#include "core/number_text.h"
#include "core/time.h"
#include "runtime/module_report.h"

namespace driftlab::replay {

namespace {
double replayed_s(const ReplayReport& r) { return seconds_between(r.start_utime, r.end_utime); }
}  // namespace

nlohmann::json to_json(const ReplaySummary& s) {
  const ReplayReport& r = s.report;
  nlohmann::json j;
  j["logs"] = s.logs;
  j["out"] = s.out;
  j["read"] = r.read;
  j["dispatched"] = r.dispatched;
  j["outputs"] = r.outputs;
  j["replayed_s"] = replayed_s(r);
  j["wall_s"] = s.wall_s;
  j["real_time_factor"] = s.wall_s > 0 ? replayed_s(r) / s.wall_s : 0;
  j["interrupted"] = r.interrupted;
  j["log_problems"] = r.log_problems;
  j["channels"] = r.channels;
  j["notes"] = s.notes;
  j["restamp"] = nlohmann::json::object();
  for (const auto& [channel, c] : s.restamp) {
    j["restamp"][channel] = {{"offset_s", c.offset_s}, {"drift_ppm", c.drift_ppm}};
  }
  j["modules"] = runtime::to_json(r.modules);
  j["injected_faults"] = r.injected.size();
  return j;
}

std::string replay_text(const ReplaySummary& s, bool timing) {
  const ReplayReport& r = s.report;
  std::string out;
  for (const auto& n : s.notes) out += n + "\n";
  const double span = replayed_s(r);
  appendf(out, "%s %.1f s of log in %.2f s (%.0fx real time): %s events in, %s module outputs%s%s\n",
          r.interrupted ? "interrupted after" : "replayed", span, s.wall_s, s.wall_s > 0 ? span / s.wall_s : 0.0,
          thousands(r.dispatched).c_str(), thousands(r.outputs).c_str(), s.out.empty() ? "" : " -> ", s.out.c_str());
  if (r.log_problems > 0) {
    appendf(out, "  %llu problems in the logs (see driftlab info)\n", static_cast<unsigned long long>(r.log_problems));
  }
  if (!r.injected.empty())
    appendf(out, "  injected %zu faults (manifest on %s)\n", r.injected.size(), s.faults_channel.c_str());
  return out + runtime::module_report_text(r.modules, timing);
}

}  // namespace driftlab::replay
