// driftlab diagnose LOG: which stream is late, lossy or on the wrong clock, from the log alone.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>

#include "analyzers/timing.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/log_input.h"
#include "apps/commands.h"
#include "apps/diagnosis_json.h"
#include "core/same_file.h"

namespace driftlab::apps {
namespace {

using analyzers::Diagnosis;
using analyzers::StreamPair;

struct DiagnoseOptions {
  std::vector<std::string> inputs;
  std::string log;
  std::string json;
  std::string html;
  analyzers::DiagnoseOptions analysis;
};

std::string ms(double seconds) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", seconds * 1e3);
  return buf;
}

/// The report as lines of text: a row per channel, the pairs, then the problems in words.
std::vector<std::string> report_lines(const Diagnosis& d, std::vector<std::string>* problems) {
  std::vector<std::string> lines;
  char buf[512];
  size_t w = 7;
  for (const auto& c : d.channels) w = std::max(w, c.name.size());
  std::snprintf(buf, sizeof(buf), "%-*s  %-7s %8s %8s %6s %5s %5s %9s %9s %9s %8s", static_cast<int>(w), "channel",
                "verdict", "count", "rate Hz", "drops", "dups", "reord", "lat p50", "lat p99", "offset", "drift");
  lines.push_back(buf);
  for (const auto& c : d.channels) {
    const int64_t drops = c.has_header ? c.seq_gaps : c.missing_by_period;
    std::snprintf(buf, sizeof(buf), "%-*s  %-7s %8lld %8.2f %6lld %5lld %5lld %9s %9s %9s %8s", static_cast<int>(w),
                  c.name.c_str(), c.verdict.c_str(), static_cast<long long>(c.count), c.rate_hz,
                  static_cast<long long>(drops), static_cast<long long>(c.duplicates),
                  static_cast<long long>(c.out_of_order_stamp),
                  c.has_header ? (ms(c.latency_s.p50) + " ms").c_str() : "-",
                  c.has_header ? (ms(c.latency_s.p99) + " ms").c_str() : "-",
                  c.clock_valid ? (ms(c.clock_offset_s) + " ms").c_str() : "-",
                  c.clock_valid ? (std::to_string(static_cast<int>(std::lround(c.clock_drift_ppm))) + " ppm").c_str() : "-");
    lines.push_back(buf);
    for (const auto& r : c.reasons) problems->push_back(c.name + ": " + r);
  }
  // A skew is shown when the streams' motions match and the windows agree on it (docs/diagnosis.md,
  // "Calibration"); the others stay in --json with their curves.
  constexpr double kConfident = 0.8;
  const auto confident = std::count_if(d.pairs.begin(), d.pairs.end(),
                                       [&](const StreamPair& p) { return p.confidence >= kConfident; });
  if (!d.pairs.empty()) {
    lines.push_back("");
    lines.push_back("skew (how much later b's stamps are than a's, from the yaw rate both observe):");
    for (const auto& p : d.pairs) {
      if (p.confidence < kConfident) continue;
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
                    d.pairs.size() - static_cast<size_t>(confident) == 1 ? "" : "s", kConfident);
      lines.push_back(buf);
    }
  }
  if (!d.tf.frames.empty()) {
    std::string roots;
    for (const auto& r : d.tf.roots) roots += (roots.empty() ? "" : ", ") + r;
    lines.push_back("");
    lines.push_back("TF: " + std::to_string(d.tf.frames.size()) + " frames, root " + roots);
    // Each dynamic transform against the data composed with it: the data in its child frame (odometry in 'odom'
    // with 'map' -> 'odom'), else the busiest channel.
    std::map<std::pair<std::string, std::string>, const analyzers::TfStampCheck*> head;
    for (const auto& c : d.tf.stamps) {
      if (c.messages == 0) continue;
      const analyzers::TfStampCheck*& h = head[{c.parent, c.child}];
      if (h == nullptr || std::pair(c.frame == c.child, c.messages) > std::pair(h->frame == h->child, h->messages))
        h = &c;
    }
    for (const auto& [edge, c] : head) {
      std::snprintf(buf, sizeof(buf),
                    "  '%s' -> '%s' (%s, every %.0f ms) with %s: %.1f ms behind it beyond its period; on arrival, "
                    "%s's stamps are up to %.0f ms past the newest transform",
                    c->parent.c_str(), c->child.c_str(), c->tf_channel.c_str(), c->period_s * 1e3, c->channel.c_str(),
                    c->offset_s * 1e3, c->channel.c_str(), c->lead_s.max * 1e3);
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
    // A loop whose commands take effect more than a command period late corrects against states the next
    // commands have already moved on from: it lags and overshoots.
    if (l.delay_valid && l.command_period_s > 0 && l.delay_s > l.command_period_s) {
      std::snprintf(buf, sizeof(buf),
                    "%s: the joints follow the commands %.0f ms late, more than the %.0f ms between "
                    "commands (a slow transport or a controller starting plans late)",
                    l.command_channel.c_str(), l.delay_s * 1e3, l.command_period_s * 1e3);
      problems->push_back(buf);
    }
    if (l.stale > 0) {
      std::snprintf(buf, sizeof(buf),
                    "%s: %lld of %lld commands arrived after their plan was over (the first at %.1f s, "
                    "the worst %.0f ms over): stamped on a clock behind, or held up",
                    l.command_channel.c_str(), static_cast<long long>(l.stale), static_cast<long long>(l.commands),
                    l.first_stale_s, l.stale_max_s * 1e3);
      problems->push_back(buf);
    }
  }
  return lines;
}

std::string html_page(const Diagnosis& d, const std::vector<std::string>& lines,
                      const std::vector<std::string>& problems) {
  auto escape = [](const std::string& s) {
    std::string out;
    for (char ch : s) {
      if (ch == '<') out += "&lt;";
      else if (ch == '>') out += "&gt;";
      else if (ch == '&') out += "&amp;";
      else out += ch;
    }
    return out;
  };
  std::string page = "<!doctype html><html><head><meta charset=\"utf-8\"><title>driftlab diagnose: " + escape(d.log) +
                     "</title><style>body{font-family:sans-serif;margin:2em}pre{background:#f6f6f6;padding:1em}"
                     "li.fault{color:#b00}</style></head><body><h1>Timing diagnosis</h1><p>" +
                     escape(d.log) + "</p><pre>";
  for (const auto& l : lines) page += escape(l) + "\n";
  page += "</pre><h2>Problems</h2><ul>";
  for (const auto& p : problems) page += "<li class=\"fault\">" + escape(p) + "</li>";
  if (problems.empty()) page += "<li>none</li>";
  return page + "</ul></body></html>\n";
}

int run_diagnose(const DiagnoseOptions& o) {
  for (const auto& [out, option] : {std::pair{o.json, "--json"}, {o.html, "--html"}}) {
    if (Status s = refuse_same_file(out, {o.log}, option); !s) return fail(s.message());
  }
  auto result = analyzers::diagnose(o.log, o.analysis);
  if (!result) return fail(result.error().message);
  const Diagnosis& d = *result;
  std::vector<std::string> problems;
  const auto lines = report_lines(d, &problems);
  if (!o.html.empty() && !write_output(o.html, html_page(d, lines, problems))) return kExitFailure;
  if (!o.json.empty()) {
    if (!write_output(o.json, to_json(d).dump(2) + "\n")) return kExitFailure;
    if (o.json == "-") return kExitOk;
  }
  for (const auto& l : lines) std::printf("%s\n", l.c_str());
  std::printf("\n");
  if (problems.empty()) {
    std::printf("no timing problems found\n");
  } else {
    std::printf("problems:\n");
    for (size_t i = 0; i < problems.size() && i < 10; ++i) std::printf("  %s\n", problems[i].c_str());
    if (problems.size() > 10) std::printf("  ... %zu more (--json lists them all)\n", problems.size() - 10);
  }
  return kExitOk;
}

}  // namespace

void add_diagnose_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<DiagnoseOptions>();
  CLI::App* cmd = app.add_subcommand(
      "diagnose", "Find skew, clock offset and drift, latency, drops, duplicates and reordering in a log.");
  cmd->add_option("log", o->inputs, kLogInputHelp)->required();
  cmd->add_option("--json", o->json, "Also write the diagnosis as JSON to this file ('-': print only the JSON)");
  cmd->add_option("--html", o->html, "Also write the report as an HTML page");
  cmd->add_option("--max-lag", o->analysis.max_lag_s, "Skew search range [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 10), "s"));
  cmd->add_option("--window", o->analysis.window_s, "Skew window [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 86400), "s"));
  cmd->callback([o, exit_code] {
    for (const auto& [out, option] : {std::pair{o->json, "--json"}, {o->html, "--html"}}) {
      if (Status s = refuse_same_file(out, o->inputs, option); !s) {  // the recording given, not only its conversion
        *exit_code = fail(s.message());
        return;
      }
    }
    auto log = event_log_for(o->inputs);
    if (!log) {
      *exit_code = fail(log.error().message);
      return;
    }
    o->log = *log;
    *exit_code = run_diagnose(*o);
  });
}

}  // namespace driftlab::apps
