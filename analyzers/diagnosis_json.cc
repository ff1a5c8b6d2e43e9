// The JSON of a timing diagnosis, as `driftlab diagnose --json` prints it and `driftlab report`, `driftlab demo`,
// the batches and the Python module read it (docs/diagnosis.md lists its fields).
#include "analyzers/diagnosis_json.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "analyzers/clock_corrections.h"
#include "core/wall_clock.h"

namespace driftlab::analyzers {

namespace {

nlohmann::json distribution_json(const Distribution& d) {
  return {{"mean", d.mean}, {"p50", d.p50}, {"p95", d.p95}, {"p99", d.p99}, {"max", d.max}};
}

}  // namespace

nlohmann::json to_json(const Diagnosis& d) {
  nlohmann::json channels = nlohmann::json::array();
  for (const auto& c : d.channels) {
    nlohmann::json gaps = nlohmann::json::array();
    for (const auto& g : c.gaps) {
      gaps.push_back({{"start_utime", g.start_utime}, {"end_utime", g.end_utime}, {"missing", g.missing}});
      if (g.end_arrival != 0) {
        gaps.back()["start_arrival_utime"] = g.start_arrival;
        gaps.back()["end_arrival_utime"] = g.end_arrival;
      }
    }
    nlohmann::json causes = nlohmann::json::array();
    for (const auto cause : c.causes) causes.push_back(cause_name(cause));
    channels.push_back(
        {{"name", c.name},
         {"type", c.type.empty() ? nlohmann::json() : nlohmann::json(c.type)},
         {"source_type", c.source_type.empty() ? nlohmann::json() : nlohmann::json(c.source_type)},
         {"domain", c.domain < 0 ? nlohmann::json() : nlohmann::json(c.domain)},
         {"peer_delay_s", std::isfinite(c.peer_delay_s) ? nlohmann::json(c.peer_delay_s) : nlohmann::json()},
         {"written_at_once", c.written_at_once},
         {"count", c.count},
         {"malformed", c.malformed},
         {"rate_hz", c.rate_hz},
         {"expected_period_s", c.expected_period_s},
         {"bursts",
          c.bursty ? nlohmann::json{{"size", c.burst_size}, {"interval_s", c.burst_interval_s}} : nlohmann::json()},
         {"irregular", c.irregular ? nlohmann::json{{"regular_fraction", c.regular_fraction}} : nlohmann::json()},
         {"drops",
          {{"seq_gaps", c.has_header && !c.seq_counted ? nlohmann::json(c.seq_gaps) : nlohmann::json()},
           {"missing_by_period", c.missing_by_period},
           {"gaps", gaps}}},
         {"duplicates", c.duplicates},
         {"out_of_order", {{"by_stamp", c.out_of_order_stamp}, {"by_arrival", c.out_of_order_arrival}}},
         {"stamps", c.has_header ? nlohmann::json{{"repeated", c.repeated_stamps},
                                                  {"zero", c.zero_stamps},
                                                  {"median_utime", c.median_stamp_utime},
                                                  {"late",
                                                   {{"count", c.late_stamps},
                                                    {"first_s", c.first_late_stamp_s},
                                                    {"max_s", c.late_stamp_max_s}}}}
                                 : nlohmann::json()},
         {"latency_s", c.latency_valid ? distribution_json(c.latency_s) : nlohmann::json()},
         {"clock", c.clock_valid ? nlohmann::json{{"offset_s", c.clock_offset_s},
                                                  {"offset_ci_s", c.clock_offset_ci_s},
                                                  {"drift_ppm", c.clock_drift_ppm},
                                                  {"drift_ci_ppm", c.clock_drift_ci_ppm}}
                                 : nlohmann::json()},
         {"transport_s", c.clock_valid ? distribution_json(c.transport_s) : nlohmann::json()},
         {"verdict", c.verdict},
         {"reasons", c.reasons},
         {"causes", causes}});
  }
  nlohmann::json pairs = nlohmann::json::array();
  for (const auto& p : d.pairs) {
    nlohmann::json windows = nlohmann::json::array();
    for (const auto& w : p.windows) {
      windows.push_back(
          {{"start_s", w.start_s}, {"end_s", w.end_s}, {"offset_s", w.offset_s}, {"confidence", w.confidence}});
    }
    nlohmann::json curve = nlohmann::json::array();
    for (const auto& [lag, c] : p.curve) curve.push_back({lag, c});
    pairs.push_back({{"a", p.a},
                     {"b", p.b},
                     {"offset_s", p.offset_s},
                     {"offset_ci_s", p.offset_ci_s},
                     {"confidence", p.confidence},
                     {"confident", p.confident()},
                     {"method", p.method},
                     {"windows", windows},
                     {"curve", curve}});
  }
  nlohmann::json loops = nlohmann::json::array();
  for (const auto& l : d.command_loops) {
    nlohmann::json curve = nlohmann::json::array();
    for (const auto& [lag, c] : l.curve) curve.push_back({lag, c});
    loops.push_back({{"command", l.command_channel},
                     {"state", l.state_channel.empty() ? nlohmann::json() : nlohmann::json(l.state_channel)},
                     {"commands", l.commands},
                     {"command_period_s", l.command_period_s},
                     {"delay_s", l.delay_valid ? nlohmann::json(l.delay_s) : nlohmann::json()},
                     {"confidence", l.confidence},
                     {"stale", {{"count", l.stale}, {"first_s", l.first_stale_s}, {"max_s", l.stale_max_s}}},
                     {"curve", curve}});
  }
  nlohmann::json tf_stamps = nlohmann::json::array();
  for (const auto& c : d.tf.stamps) {
    tf_stamps.push_back({{"transform", c.parent + " -> " + c.child},
                         {"tf_channel", c.tf_channel},
                         {"channel", c.channel},
                         {"frame", c.frame},
                         {"messages", c.messages},
                         {"period_s", c.period_s},
                         {"offset_s", c.offset_s},
                         {"lead_s", distribution_json(c.lead_s)},
                         {"wait_s", distribution_json(c.wait_s)},
                         {"never", c.never},
                         {"tf_latency_s", c.tf_latency_s},
                         {"data_latency_s", c.data_latency_s}});
  }
  nlohmann::json physics = nlohmann::json::array();
  for (const auto& p : d.physics) {
    physics.push_back({{"channel", p.channel},
                       {"messages", p.messages},
                       {"real_time_factor_mean", p.real_time_factor_mean},
                       {"real_time_factor_min", p.real_time_factor_min},
                       {"sim_step_s", p.sim_step_s},
                       {"wall_step_max_s", p.wall_step_max_s}});
  }
  nlohmann::json timesync = nlohmann::json::array();
  for (const auto& t : d.timesync) {
    timesync.push_back({{"channel", t.channel},
                        {"messages", t.messages},
                        {"round_trip_s", distribution_json(t.round_trip_s)},
                        {"offset_first_s", t.offset_first_s},
                        {"offset_last_s", t.offset_last_s},
                        {"offset_min_s", t.offset_min_s},
                        {"offset_max_s", t.offset_max_s},
                        {"resyncs", t.resyncs},
                        {"resync_at_s", t.resync_at_s},
                        {"residual_s", distribution_json(t.residual_s)}});
  }
  nlohmann::json domains = nlohmann::json::array();
  for (const auto& x : d.domains) {
    domains.push_back({{"kind", x.kind},
                       {"description", x.description},
                       {"channels", x.channels},
                       {"offset_s", x.offset_s},
                       {"mapped", x.mapped},
                       {"reference", x.reference},
                       {"rate", x.rate_valid ? nlohmann::json(x.rate) : nlohmann::json()},
                       {"rate_min", x.rate_valid ? nlohmann::json(x.rate_min) : nlohmann::json()},
                       {"rate_max", x.rate_valid ? nlohmann::json(x.rate_max) : nlohmann::json()},
                       {"mapping", x.mapping}});
  }
  nlohmann::json tf_edges = nlohmann::json::array();
  for (const auto& e : d.tf.edges) {
    tf_edges.push_back({{"parent", e.parent},
                        {"child", e.child},
                        {"channel", e.channel},
                        {"static", e.is_static},
                        {"count", e.count},
                        {"rate_hz", e.rate_hz},
                        {"out_of_order", e.out_of_order},
                        {"age_s", e.is_static ? nlohmann::json() : distribution_json(e.age_s)},
                        {"ahead", e.ahead}});
  }
  return {{"log", d.log},
          {"start_utime", d.start_utime},
          {"end_utime", d.end_utime},
          {"log_problems", d.log_problems},
          {"clock_domains", domains},
          {"channels", channels},
          {"pairs", pairs},
          {"tf",
           {{"frames", d.tf.frames},
            {"roots", d.tf.roots},
            {"edges", tf_edges},
            {"stamps", tf_stamps},
            {"problems", d.tf.problems}}},
          {"command_loops", loops},
          {"physics", physics},
          {"timesync", timesync}};
}

const char* severity_name(Severity s) {
  switch (s) {
    case Severity::kWarn: return "warn";
    case Severity::kFault: return "fault";
    case Severity::kOk: break;
  }
  return "ok";
}

Severity severity_from_name(std::string_view name) {
  return name == "fault" ? Severity::kFault : name == "warn" ? Severity::kWarn : Severity::kOk;
}

Result<DiagnosisSummary> summarize(const nlohmann::json& diagnosis) {
  // A clock of another epoch (simulation time) has no offset of its own: its streams' clocks are against its peers.
  auto on_mapped_clock = [&](const nlohmann::json& c) {
    const auto& domain = c.value("domain", nlohmann::json());
    const auto& domains = diagnosis.value("clock_domains", nlohmann::json::array());
    return domain.is_number() && domain.get<size_t>() < domains.size() &&
           domains[domain.get<size_t>()].value("mapped", false);
  };
  auto rank = [&](const nlohmann::json& c) {
    const auto& causes = c.value("causes", nlohmann::json::array());
    return problem_rank(c.at("verdict").get<std::string>(),
                        causes.empty() ? Cause::kSymptom : cause_from_name(causes[0].get<std::string>()),
                        c.at("reasons").size());
  };
  DiagnosisSummary out;
  try {
    const nlohmann::json* worst = nullptr;
    size_t worst_index = 0;
    for (const auto& c : diagnosis.at("channels")) {
      const std::string name = c.at("name");
      if (rank(c) > 0 && (worst == nullptr || rank(c) > rank(*worst))) {
        worst = &c;
        worst_index = out.streams.size();
      }
      const Severity verdict = severity_from_name(c.at("verdict").get<std::string>());
      out.streams.push_back({name, verdict, c.at("reasons").get<std::vector<std::string>>(),
                             c.value("causes", nlohmann::json::array()).get<std::vector<std::string>>()});
      out.fault_streams += verdict == Severity::kFault;
      out.warn_streams += verdict == Severity::kWarn;
      const auto& clock = c.at("clock");
      if (clock.is_object() && !on_mapped_clock(c) && clock_ahead(clock.at("offset_s").get<double>())) {
        out.clocks_ahead_s[name] = clock.at("offset_s").get<double>();
      }
      const auto& d = c.at("drops");
      const int64_t n =
          d.at("seq_gaps").is_number() ? d.at("seq_gaps").get<int64_t>() : d.at("missing_by_period").get<int64_t>();
      if (n > 0) out.drops[name] = n;
    }
    if (worst != nullptr) out.worst_stream = out.streams[worst_index];
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("not a diagnosis (driftlab diagnose --json): ") + e.what()};
  }
  return out;
}

nlohmann::json to_json(const DiagnosisSummary& s) {
  nlohmann::json worst;
  if (s.worst_stream) {
    worst = {{"name", s.worst_stream->name},
             {"verdict", severity_name(s.worst_stream->verdict)},
             {"reasons", s.worst_stream->reasons},
             {"causes", s.worst_stream->causes}};
  }
  return {{"worst_stream", worst}, {"clocks_ahead_s", s.clocks_ahead_s}, {"drops", s.drops}};
}

nlohmann::json flight_log_json(const FlightLogDiagnosis& f) {
  nlohmann::json dropouts = nlohmann::json::array();
  for (const auto& d : f.dropouts) dropouts.push_back({{"at_s", d.at_s}, {"duration_s", d.duration_s}});
  nlohmann::json delays = nlohmann::json::array();
  for (const auto& s : f.sample_delays) {
    delays.push_back({{"channel", s.channel},
                      {"topic", s.topic},
                      {"sensor", s.sensor},
                      {"count", s.count},
                      {"p50_s", s.p50_s},
                      {"p99_s", s.p99_s},
                      {"max_s", s.max_s},
                      {"negative", s.negative}});
  }
  nlohmann::json imu = nlohmann::json::array();
  for (const auto& i : f.imu) {
    imu.push_back({{"channel", i.channel},
                   {"topic", i.topic},
                   {"intervals", i.intervals},
                   {"nominal_s", i.nominal_s},
                   {"share_1x", i.share_1x},
                   {"share_2x", i.share_2x},
                   {"share_0", i.share_0},
                   {"share_other", i.share_other},
                   {"longest_s", i.longest_s},
                   {"longest_at_s", i.longest_at_s},
                   {"gaps", i.gaps}});
  }
  nlohmann::json estimator = nlohmann::json::array();
  for (const auto& s : f.estimator) {
    estimator.push_back({{"channel", s.channel},
                         {"field", s.field},
                         {"kind", s.kind},
                         {"samples", s.samples},
                         {"over", s.over},
                         {"max", s.max},
                         {"time_over_s", s.time_over_s},
                         {"first_s", s.first_s < 0 ? nlohmann::json() : nlohmann::json(s.first_s)}});
  }
  nlohmann::json loss = nlohmann::json::array();
  for (const auto& l : f.imu_loss) loss.push_back({{"channel", l.channel}, {"field", l.field}, {"growth", l.growth}});
  nlohmann::json timeline = nlohmann::json::array();
  for (const auto& e : f.timeline) {
    timeline.push_back({{"kind", e.kind}, {"what", e.what}, {"start_s", e.start_s}, {"end_s", e.end_s}});
  }
  return {{"start_utime", f.start_utime},
          {"utc", flight_utc_json(f.utc)},
          {"fusion_horizon",
           f.horizon_s > 0 ? nlohmann::json{{"s", f.horizon_s}, {"channel", f.horizon_channel}} : nlohmann::json()},
          {"dropouts",
           {{"count", f.dropout_count}, {"total_s", f.dropout_total_s}, {"max_s", f.dropout_max_s}, {"at", dropouts}}},
          {"sample_delays", delays},
          {"imu_intervals", imu},
          {"estimator", estimator},
          {"imu_loss", loss},
          {"timeline", timeline},
          {"problems", f.problems}};
}

nlohmann::json flight_utc_json(const FlightUtc& u) {
  if (!u.known) return nullptr;
  return {{"start", format_utime(u.start_utc_us)},
          {"start_utc_us", u.start_utc_us},
          {"start_utime", u.start_utime},
          {"boot_to_utc_us", u.boot_to_utc_us},
          {"fixes", u.fixes},
          {"spread_s", u.spread_s},
          {"channel", u.channel}};
}

Result<DiagnoseRun> run_diagnosis(const std::string& log, const DiagnoseOptions& options) {
  auto d = diagnose(log, options);
  if (!d) return d.error();
  DiagnoseRun run{std::move(*d), {}};
  if (run.diagnosis.flight_log) {  // a second pass, for flight logs only
    auto flight = diagnose_flight_log(log);
    if (!flight) return flight.error();
    run.flight = std::move(*flight);
  }
  return run;
}

nlohmann::json diagnose_json(const DiagnoseRun& run) {
  nlohmann::json j = to_json(run.diagnosis);
  if (run.flight.present) j["flight_log"] = flight_log_json(run.flight);
  return j;
}

}  // namespace driftlab::analyzers
