// The JSON of `driftlab diagnose --json`, also read by `driftlab report` and `driftlab demo`.
#include "apps/diagnosis_json.h"

#include "analyzers/clock_corrections.h"
#include "apps/cli_util.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace driftlab::apps {

namespace {

nlohmann::json distribution_json(const analyzers::Distribution& d) {
  return {{"mean", d.mean}, {"p50", d.p50}, {"p95", d.p95}, {"p99", d.p99}, {"max", d.max}};
}

}  // namespace

nlohmann::json to_json(const analyzers::Diagnosis& d) {
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
    for (const auto cause : c.causes) causes.push_back(analyzers::cause_name(cause));
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
      windows.push_back({{"start_s", w.start_s}, {"end_s", w.end_s}, {"offset_s", w.offset_s}, {"confidence", w.confidence}});
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

nlohmann::json diagnosis_summary(const nlohmann::json& diagnosis) {
  // A clock of another epoch (simulation time) has no offset of its own: its streams' clocks are against its peers.
  auto on_mapped_clock = [&](const nlohmann::json& c) {
    const auto& domain = c.value("domain", nlohmann::json());
    const auto& domains = diagnosis.value("clock_domains", nlohmann::json::array());
    return domain.is_number() && domain.get<size_t>() < domains.size() &&
           domains[domain.get<size_t>()].value("mapped", false);
  };
  auto rank = [&](const nlohmann::json& c) {
    const auto& causes = c.value("causes", nlohmann::json::array());
    return analyzers::problem_rank(
        c.at("verdict").get<std::string>(),
        causes.empty() ? analyzers::Cause::kSymptom : analyzers::cause_from_name(causes[0].get<std::string>()),
        c.at("reasons").size());
  };
  const nlohmann::json* worst = nullptr;
  nlohmann::json ahead = nlohmann::json::object(), drops = nlohmann::json::object();
  for (const auto& c : diagnosis.at("channels")) {
    const std::string name = c.at("name");
    if (rank(c) > 0 && (worst == nullptr || rank(c) > rank(*worst))) worst = &c;
    const auto& clock = c.at("clock");
    if (clock.is_object() && !on_mapped_clock(c) && analyzers::clock_ahead(clock.at("offset_s").get<double>())) {
      ahead[name] = clock.at("offset_s");
    }
    const auto& d = c.at("drops");
    const int64_t n = d.at("seq_gaps").is_number() ? d.at("seq_gaps").get<int64_t>() : d.at("missing_by_period").get<int64_t>();
    if (n > 0) drops[name] = n;
  }
  return {
      {"worst_stream", worst == nullptr ? nlohmann::json()
                                        : nlohmann::json{{"name", worst->at("name")},
                                                         {"verdict", worst->at("verdict")},
                                                         {"reasons", worst->at("reasons")},
                                                         {"causes", worst->value("causes", nlohmann::json::array())}}},
      {"clocks_ahead_s", ahead},
      {"drops", drops}};
}

}  // namespace driftlab::apps

namespace driftlab::apps {

nlohmann::json flight_log_json(const analyzers::FlightLogDiagnosis& f) {
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

nlohmann::json flight_utc_json(const analyzers::FlightUtc& u) {
  if (!u.known) return nullptr;
  return {{"start", format_utime(u.start_utc_us)},
          {"start_utc_us", u.start_utc_us},
          {"start_utime", u.start_utime},
          {"boot_to_utc_us", u.boot_to_utc_us},
          {"fixes", u.fixes},
          {"spread_s", u.spread_s},
          {"channel", u.channel}};
}

std::string flight_utc_line(const analyzers::FlightUtc& u) {
  if (!u.known) return "";
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "UTC (GNSS time, %s, %lld fixes agreeing within %.1f ms): the log starts (boot time %.6f s) at %s; UTC "
                "= boot time + %lld.%06lld s",
                u.channel.c_str(), static_cast<long long>(u.fixes), u.spread_s * 1e3,
                static_cast<double>(u.start_utime) * 1e-6, format_utime(u.start_utc_us).c_str(),
                static_cast<long long>(u.boot_to_utc_us / 1000000),
                static_cast<long long>(std::abs(u.boot_to_utc_us % 1000000)));
  return buf;
}

std::vector<std::string> flight_log_lines(const analyzers::FlightLogDiagnosis& f) {
  std::vector<std::string> lines;
  if (!f.present) return lines;
  char buf[512];
  lines.push_back("flight log (PX4 ULog; times from the log's start):");
  if (f.utc.known) lines.push_back("  " + flight_utc_line(f.utc));
  if (f.dropout_count == 0) {
    lines.push_back("  logger dropouts: none");
  } else {
    std::string where;
    for (size_t i = 0; i < f.dropouts.size() && i < 8; ++i) {
      std::snprintf(buf, sizeof buf, "%s%.0f ms at %.1f s", i ? ", " : "", f.dropouts[i].duration_s * 1e3,
                    f.dropouts[i].at_s);
      where += buf;
    }
    if (f.dropouts.size() > 8) where += ", ...";
    std::snprintf(buf, sizeof buf, "  logger dropouts: %lld, %.0f ms in all, the longest %.0f ms (%s)",
                  static_cast<long long>(f.dropout_count), f.dropout_total_s * 1e3, f.dropout_max_s * 1e3,
                  where.c_str());
    lines.push_back(buf);
  }
  size_t w = 7;
  for (const auto& s : f.sample_delays) w = std::max(w, s.channel.size());
  for (const auto& s : f.imu) w = std::max(w, s.channel.size());
  const int iw = static_cast<int>(w);
  const auto sensors = std::count_if(f.sample_delays.begin(), f.sample_delays.end(),
                                     [](const analyzers::SampleDelay& s) { return s.sensor; });
  if (sensors > 0) {
    lines.push_back("  sensors, sample to publication (timestamp - timestamp_sample; other topics in --json):");
    std::snprintf(buf, sizeof buf, "    %-*s %8s %9s %9s %9s", iw, "channel", "count", "p50 ms", "p99 ms", "max ms");
    lines.push_back(buf);
    for (const auto& s : f.sample_delays) {
      if (!s.sensor) continue;
      std::snprintf(buf, sizeof buf, "    %-*s %8lld %9.2f %9.2f %9.2f", iw, s.channel.c_str(),
                    static_cast<long long>(s.count), s.p50_s * 1e3, s.p99_s * 1e3, s.max_s * 1e3);
      lines.push_back(buf);
    }
  }
  if (f.horizon_s > 0) {
    std::snprintf(buf, sizeof buf, "  estimator fusion horizon: %.0f ms behind its newest IMU sample (%s)",
                  f.horizon_s * 1e3, f.horizon_channel.c_str());
    lines.push_back(buf);
  }
  if (!f.imu.empty()) {
    lines.push_back("  IMU intervals (against the median period; a scheduler that skips shows ~2x and ~0):");
    std::snprintf(buf, sizeof buf, "    %-*s %8s %9s %6s %6s %6s %6s %11s", iw, "channel", "count", "period", "~1x",
                  "~2x", "~0", "other", "longest");
    lines.push_back(buf);
    for (const auto& s : f.imu) {
      std::snprintf(buf, sizeof buf, "    %-*s %8lld %6.1f ms %5.1f%% %5.1f%% %5.1f%% %5.1f%% %8.1f ms", iw,
                    s.channel.c_str(), static_cast<long long>(s.intervals), s.nominal_s * 1e3, s.share_1x * 100,
                    s.share_2x * 100, s.share_0 * 100, s.share_other * 100, s.longest_s * 1e3);
      lines.push_back(buf);
    }
  }
  int ratios = 0;
  const analyzers::EstimatorCheck* highest = nullptr;
  for (const auto& s : f.estimator) {
    if (s.kind != "test_ratio") continue;
    ++ratios;
    if (!highest || s.max > highest->max) highest = &s;
  }
  if (!f.estimator.empty()) {
    lines.push_back("  estimator (innovation test ratios over 1: the measurement rejected):");
    if (highest) {
      std::snprintf(buf, sizeof buf, "    %d test ratios; the highest %.2f (%s %s)", ratios, highest->max,
                    highest->channel.c_str(), highest->field.c_str());
      lines.push_back(buf);
    }
    for (const auto& s : f.estimator) {
      if (s.over == 0) continue;
      char max[32] = "";
      if (s.kind == "test_ratio") std::snprintf(max, sizeof max, "; max %.2f", s.max);
      std::snprintf(buf, sizeof buf, "    %s %s: %s in %lld of %lld samples (%.1f s, first at %.1f s)%s",
                    s.channel.c_str(), s.field.c_str(),
                    s.kind == "test_ratio" ? "over 1"
                    : s.kind == "timeout"  ? "timed out"
                                           : "rejected",
                    static_cast<long long>(s.over), static_cast<long long>(s.samples), s.time_over_s, s.first_s, max);
      lines.push_back(buf);
    }
  }
  std::string slip, errors;
  double error_total = 0;
  for (const auto& l : f.imu_loss) {
    if (l.field == "time_slip") {
      std::snprintf(buf, sizeof buf, "%s%.0f ms (%s)", slip.empty() ? "" : ", ", l.growth * 1e3, l.channel.c_str());
      slip += buf;
    } else {
      error_total += l.growth;
      if (l.growth > 0) {
        std::snprintf(buf, sizeof buf, "%s%.0f (%s %s)", errors.empty() ? "" : ", ", l.growth, l.channel.c_str(),
                      l.field.c_str());
        errors += buf;
      }
    }
  }
  if (!slip.empty()) lines.push_back("  IMU data the estimator dropped (time_slip over the log): " + slip);
  const bool counted = std::any_of(f.imu_loss.begin(), f.imu_loss.end(),
                                   [](const analyzers::ImuLoss& l) { return l.field != "time_slip"; });
  if (counted) {
    lines.push_back("  IMU driver errors (vehicle_imu_status error counts over the log): " +
                    (error_total > 0 ? errors : std::string("none")));
  }
  return lines;
}

Result<DiagnoseRun> run_diagnosis(const std::string& log, const analyzers::DiagnoseOptions& options) {
  auto d = analyzers::diagnose(log, options);
  if (!d) return d.error();
  DiagnoseRun run{std::move(*d), {}};
  if (run.diagnosis.flight_log) {  // a second pass, for flight logs only
    auto flight = analyzers::diagnose_flight_log(log);
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

}  // namespace driftlab::apps
