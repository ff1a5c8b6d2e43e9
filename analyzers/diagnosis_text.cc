#include "analyzers/diagnosis_text.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/number_text.h"
#include "core/wall_clock.h"

namespace driftlab::analyzers {
namespace {

std::string ms(double seconds) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", seconds * 1e3);
  return buf;
}

/// The TF tree as tf2's view_frames draws it, a line per frame under its parent: who broadcasts each transform,
/// how often, and how old it is on arrival.
std::vector<std::string> tf_tree_lines(const TfDiagnosis& tf) {
  std::map<std::string, std::vector<const TfEdge*>> children;
  for (const auto& e : tf.edges) children[e.parent].push_back(&e);
  std::vector<std::string> out;
  char buf[512];
  // Depth first from each root; a frame is drawn once (a frame with two parents under the first).
  std::set<std::string> drawn;
  std::vector<std::pair<const TfEdge*, std::string>> stack;  // (edge, indent)
  for (const auto& root : tf.roots) {
    out.push_back(root);
    drawn.insert(root);
    const auto& kids = children[root];
    for (auto it = kids.rbegin(); it != kids.rend(); ++it) stack.emplace_back(*it, "");
    while (!stack.empty()) {
      auto [e, indent] = stack.back();
      stack.pop_back();
      if (!drawn.insert(e->child).second) continue;
      if (e->is_static && children[e->child].empty()) {
        // A frame's static leaves on one line (a robot's links): the tree stays readable.
        std::string leaves = e->child;
        while (!stack.empty() && stack.back().second == indent && stack.back().first->is_static &&
               stack.back().first->channel == e->channel && children[stack.back().first->child].empty()) {
          if (drawn.insert(stack.back().first->child).second) leaves += ", " + stack.back().first->child;
          stack.pop_back();
        }
        std::snprintf(buf, sizeof(buf), "%s+- %s  (%s, static)", indent.c_str(), leaves.c_str(), e->channel.c_str());
      } else if (e->is_static) {
        std::snprintf(buf, sizeof(buf), "%s+- %s  (%s, static)", indent.c_str(), e->child.c_str(), e->channel.c_str());
      } else {
        std::snprintf(buf, sizeof(buf),
                      "%s+- %s  (%s, %lld at %.1f Hz, %.1f ms old on arrival (p50), %lld "
                      "reordered)",
                      indent.c_str(), e->child.c_str(), e->channel.c_str(), static_cast<long long>(e->count),
                      e->rate_hz, e->age_s.p50 * 1e3, static_cast<long long>(e->out_of_order));
      }
      out.push_back(buf);
      const auto& next = children[e->child];
      for (auto it = next.rbegin(); it != next.rend(); ++it) stack.emplace_back(*it, indent + "   ");
    }
  }
  return out;
}

/// The report as lines of text: a row per channel, the pairs, then the problems in words.
std::vector<std::string> report_lines(const Diagnosis& d, std::vector<std::string>* problems) {
  std::vector<std::string> lines;
  char buf[1024];
  size_t w = 7;
  for (const auto& c : d.channels) w = std::max(w, c.name.size());
  // Streams on clocks of their own (simulation time, time since boot): a column says which clock, and their
  // latency is against the fastest stream on it (docs/diagnosis.md, "Clock domains").
  const bool foreign =
      std::any_of(d.domains.begin(), d.domains.end(), [](const ClockDomain& x) { return x.kind != "recorder"; });
  auto on_own_clock = [&](const ChannelTiming& c) {
    return c.domain >= 0 && d.domains[static_cast<size_t>(c.domain)].mapped;
  };
  std::snprintf(buf, sizeof(buf), "%-*s  %-7s %8s %8s %6s %5s %5s %9s %9s %9s %8s%s", static_cast<int>(w), "channel",
                "verdict", "count", "rate Hz", "drops", "dups", "reord", "lat p50", "lat p99", "offset", "drift",
                foreign ? "  clock" : "");
  lines.push_back(buf);
  for (const auto& c : d.channels) {
    const int64_t drops = c.has_header && !c.seq_counted ? c.seq_gaps : c.missing_by_period;
    const bool offset = c.clock_valid && !on_own_clock(c);  // on a clock of its own, an offset is the domain's
    std::string clock;
    if (foreign) clock = "  " + (c.domain < 0 ? std::string("-") : "clock " + std::to_string(c.domain + 1));
    std::snprintf(
        buf, sizeof(buf), "%-*s  %-7s %8lld %8.2f %6lld %5lld %5lld %9s %9s %9s %8s%s", static_cast<int>(w),
        c.name.c_str(), c.verdict.c_str(), static_cast<long long>(c.count), c.rate_hz, static_cast<long long>(drops),
        static_cast<long long>(c.duplicates), static_cast<long long>(c.out_of_order_stamp),
        c.latency_valid ? (ms(c.latency_s.p50) + " ms").c_str() : "-",
        c.latency_valid ? (ms(c.latency_s.p99) + " ms").c_str() : "-",
        offset ? (ms(c.clock_offset_s) + " ms").c_str() : "-",
        c.clock_valid ? (std::to_string(static_cast<int>(std::lround(c.clock_drift_ppm))) + " ppm").c_str() : "-",
        clock.c_str());
    lines.push_back(buf);
  }
  // The problems worst stream first (docs/diagnosis.md, "The headline"), each stream's cause before its symptoms.
  std::vector<const ChannelTiming*> worst_first;
  for (const auto& c : d.channels) worst_first.push_back(&c);
  auto rank = [](const ChannelTiming* c) {
    return problem_rank(c->verdict, c->causes.empty() ? Cause::kSymptom : c->causes[0], c->reasons.size());
  };
  std::stable_sort(worst_first.begin(), worst_first.end(),
                   [&](const auto* a, const auto* b) { return rank(a) > rank(b); });
  for (const auto* c : worst_first) {
    for (const auto& r : c->reasons) problems->push_back(c->name + ": " + r);
  }
  // Streams without a sequence number or a steady period: their drops cannot be told, said once.
  std::string untold;
  for (const auto& c : d.channels) {
    if (c.seq_counted && c.irregular) untold += (untold.empty() ? "" : ", ") + c.name;
  }
  if (!untold.empty()) {
    lines.push_back("");
    lines.push_back("drops cannot be told (no sequence number travelled, and no steady period): " + untold);
  }
  // Results written at once (a SLAM's optimised trajectory at the end): not streams, said once.
  std::string at_once;
  for (const auto& c : d.channels) {
    if (c.written_at_once) at_once += (at_once.empty() ? "" : ", ") + c.name;
  }
  if (!at_once.empty()) {
    lines.push_back("");
    lines.push_back("written at once, not streamed (results, whose times are not judged): " + at_once);
  }
  if (foreign) {
    lines.push_back("");
    lines.push_back(
        "clocks (latency on a clock of another epoch is against the simulator's /clock where recorded, else the "
        "fastest stream on it):");
    for (size_t i = 0; i < d.domains.size(); ++i) {
      const ClockDomain& x = d.domains[i];
      std::string list;
      for (const auto& ch : x.channels) list += (list.empty() ? "" : ", ") + ch;
      const std::string against = x.reference.empty() ? "" : " (against " + x.reference + ")";
      std::snprintf(buf, sizeof(buf), "  clock %zu: %s%s: %s", i + 1, x.description.c_str(), against.c_str(),
                    list.c_str());
      lines.push_back(buf);
    }
  }
  // A skew is shown when the streams' motions match and the windows agree on it (docs/diagnosis.md,
  // "Calibration"); the others stay in --json with their curves.
  const auto confident =
      std::count_if(d.pairs.begin(), d.pairs.end(), [](const StreamPair& p) { return p.confident(); });
  if (!d.pairs.empty()) {
    lines.push_back("");
    lines.push_back("skew (how much later b's stamps are than a's, from the yaw rate both observe):");
    for (const auto& p : d.pairs) {
      if (!p.confident()) continue;
      std::snprintf(buf, sizeof(buf), "  %s -> %s: %+.1f ms (95%%: %+.1f to %+.1f; confidence %.2f)", p.a.c_str(),
                    p.b.c_str(), p.offset_s * 1e3, p.offset_ci_s[0] * 1e3, p.offset_ci_s[1] * 1e3, p.confidence);
      lines.push_back(buf);
      if (std::abs(p.offset_s) >= 0.002) {
        std::snprintf(buf, sizeof(buf), "%s is stamped %.1f ms %s than %s for the same motion", p.b.c_str(),
                      std::abs(p.offset_s) * 1e3, p.offset_s > 0 ? "later" : "earlier", p.a.c_str());
        problems->push_back(buf);
      }
    }
    if (static_cast<size_t>(confident) < d.pairs.size()) {
      std::snprintf(buf, sizeof(buf),
                    "  %zu pair%s without a clear, consistent lag (confidence below %.1f): not "
                    "shown (--json has them)",
                    d.pairs.size() - static_cast<size_t>(confident),
                    d.pairs.size() - static_cast<size_t>(confident) == 1 ? "" : "s", kConfidentCorrelation);
      lines.push_back(buf);
    }
  }
  if (!d.tf.frames.empty()) {
    std::string roots;
    for (const auto& r : d.tf.roots) roots += (roots.empty() ? "" : ", ") + r;
    lines.push_back("");
    lines.push_back("TF: " + std::to_string(d.tf.frames.size()) + " frames, root " + roots);
    for (const auto& l : tf_tree_lines(d.tf)) lines.push_back("  " + l);
    // Each dynamic transform against the data composed with it: the data in its child frame (odometry in 'odom'
    // with 'map' -> 'odom'), else the busiest channel.
    std::map<std::pair<std::string, std::string>, const TfStampCheck*> head;
    for (const auto& c : d.tf.stamps) {
      if (c.messages == 0) continue;
      const TfStampCheck*& h = head[{c.parent, c.child}];
      if (h == nullptr || std::pair(c.frame == c.child, c.messages) > std::pair(h->frame == h->child, h->messages))
        h = &c;
    }
    for (const auto& [edge, c] : head) {
      // Stamped behind the data beyond its period, or (post-dated) ahead of it.
      std::snprintf(buf, sizeof(buf),
                    "  '%s' -> '%s' (%s, every %.0f ms) with %s: %.1f ms %s beyond its period; on arrival, "
                    "%s's stamps are up to %.0f ms past the newest transform",
                    c->parent.c_str(), c->child.c_str(), c->tf_channel.c_str(), c->period_s * 1e3, c->channel.c_str(),
                    std::abs(c->offset_s) * 1e3, c->offset_s < 0 ? "ahead of it" : "behind it", c->channel.c_str(),
                    c->lead_s.max * 1e3);
      lines.push_back(buf);
    }
  }
  for (const auto& p : d.tf.problems) problems->push_back("TF: " + p);
  // A simulator slower than real time: below 0.9, what runs on the wall clock sees every stream slowed. First: it
  // explains the drifting clocks and the slow rates of every stream on the simulation's clock.
  for (auto p = d.physics.rbegin(); p != d.physics.rend(); ++p) {
    if (!(p->real_time_factor_mean < 0.9)) continue;
    std::snprintf(buf, sizeof(buf),
                  "%s: the simulation ran at %.0f%% of real time (physics updates of %.1f ms of simulated time took "
                  "up to %.1f ms): streams on the simulation's clock reach the wall clock at %.0f%% of their rate, "
                  "their stamps falling behind it",
                  p->channel.c_str(), p->real_time_factor_mean * 100, p->sim_step_s * 1e3, p->wall_step_max_s * 1e3,
                  p->real_time_factor_mean * 100);
    problems->insert(problems->begin(), buf);
  }
  if (!d.timesync.empty()) {
    lines.push_back("");
    lines.push_back("time sync (the offset between two computers' clocks, as the link estimated it):");
    for (const auto& t : d.timesync) {
      std::snprintf(buf, sizeof(buf),
                    "  %s: %lld estimates, round trip %.1f ms (p50; p99 %.1f ms), offset %+.3f s to %+.3f s, %lld "
                    "restart%s",
                    t.channel.c_str(), static_cast<long long>(t.messages), t.round_trip_s.p50 * 1e3,
                    t.round_trip_s.p99 * 1e3, t.offset_min_s, t.offset_max_s, static_cast<long long>(t.resyncs),
                    t.resyncs == 1 ? "" : "s");
      lines.push_back(buf);
    }
  }
  bool loops_header = false;
  for (const auto& l : d.command_loops) {
    if (l.state_channel.empty() && l.stale == 0) continue;
    if (!loops_header) {
      loops_header = true;
      lines.push_back("");
      lines.push_back("command loops (the delay from a command to the joints' motion, measured from the motion):");
    }
    if (l.delay_valid) {
      std::snprintf(buf, sizeof(buf), "  %s -> %s: %.1f ms (confidence %.2f), %lld commands every %.0f ms",
                    l.command_channel.c_str(), l.state_channel.c_str(), l.delay_s * 1e3, l.confidence,
                    static_cast<long long>(l.commands), l.command_period_s * 1e3);
    } else {
      std::snprintf(buf, sizeof(buf),
                    "  %s -> %s: no delay measured (the joints do not follow the commanded "
                    "motion clearly: confidence %.2f)",
                    l.command_channel.c_str(),
                    l.state_channel.empty() ? "(no joint states of its joints)" : l.state_channel.c_str(),
                    l.confidence);
    }
    lines.push_back(buf);
  }
  return lines;
}

}  // namespace

std::string flight_utc_line(const FlightUtc& u) {
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

std::vector<std::string> flight_log_lines(const FlightLogDiagnosis& f) {
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
  const auto sensors =
      std::count_if(f.sample_delays.begin(), f.sample_delays.end(), [](const SampleDelay& s) { return s.sensor; });
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
  const EstimatorCheck* highest = nullptr;
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
  const bool counted =
      std::any_of(f.imu_loss.begin(), f.imu_loss.end(), [](const ImuLoss& l) { return l.field != "time_slip"; });
  if (counted) {
    lines.push_back("  IMU driver errors (vehicle_imu_status error counts over the log): " +
                    (error_total > 0 ? errors : std::string("none")));
  }
  return lines;
}

DiagnosisText diagnosis_text(const DiagnoseRun& run) {
  DiagnosisText t;
  t.lines = report_lines(run.diagnosis, &t.problems);
  // A PX4 flight log: the flight controller's own account of its timing and its estimator, its problems first (a
  // logger dropout explains the gaps every channel shows at it).
  if (run.flight.present) {
    t.lines.emplace_back();
    for (auto& l : flight_log_lines(run.flight)) t.lines.push_back(std::move(l));
    t.problems.insert(t.problems.begin(), run.flight.problems.begin(), run.flight.problems.end());
  }
  return t;
}

std::string diagnosis_html(const Diagnosis& d, const DiagnosisText& text) {
  auto escape = [](const std::string& s) {
    std::string out;
    for (char ch : s) {
      if (ch == '<')
        out += "&lt;";
      else if (ch == '>')
        out += "&gt;";
      else if (ch == '&')
        out += "&amp;";
      else
        out += ch;
    }
    return out;
  };
  std::string page = "<!doctype html><html><head><meta charset=\"utf-8\"><title>driftlab diagnose: " + escape(d.log) +
                     "</title><style>body{font-family:sans-serif;margin:2em}pre{background:#f6f6f6;padding:1em}"
                     "li.fault{color:#b00}</style></head><body><h1>Timing diagnosis</h1><p>" +
                     escape(d.log) + "</p><pre>";
  for (const auto& l : text.lines) page += escape(l) + "\n";
  page += "</pre><h2>Problems</h2><ul>";
  for (const auto& p : text.problems) page += "<li class=\"fault\">" + escape(p) + "</li>";
  if (text.problems.empty()) page += "<li>none</li>";
  return page + "</ul></body></html>\n";
}

Severity worst_severity(const Diagnosis& d, const DiagnosisText& text) {
  if (std::any_of(d.channels.begin(), d.channels.end(), [](const ChannelTiming& c) { return c.verdict == "fault"; })) {
    return Severity::kFault;
  }
  const bool warn =
      std::any_of(d.channels.begin(), d.channels.end(), [](const ChannelTiming& c) { return c.verdict != "ok"; });
  return warn || !text.problems.empty() ? Severity::kWarn : Severity::kOk;
}

std::string to_text(const DiagnosisText& text) {
  std::string out;
  for (const auto& l : text.lines) out += l + "\n";
  if (text.problems.empty()) return out + "\nno timing problems found\n";
  out += "\nproblems:\n";
  for (size_t i = 0; i < text.problems.size() && i < 10; ++i) out += "  " + text.problems[i] + "\n";
  if (text.problems.size() > 10) appendf(out, "  ... %zu more (--json lists them all)\n", text.problems.size() - 10);
  return out;
}

}  // namespace driftlab::analyzers
