// The text of `driftlab diagnose` and `driftlab info` for a PX4 flight log.
#include "apps/diagnosis_text.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/wall_clock.h"

namespace driftlab::apps {

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

}  // namespace driftlab::apps
