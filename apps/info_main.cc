// driftlab info LOG [--json]: what a log holds (channels, types, rates, time range) and what is wrong with it.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include "analyzers/diagnosis_json.h"
#include "analyzers/diagnosis_text.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/log_format.h"
#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/time.h"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/recorder_stats_t.hpp"
#include "formats/ulog_messages.h"
#include "lcmtypes/seq_origin.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

struct InfoOptions {
  std::vector<std::string> inputs;
  std::string log;
  JsonOutput json;
  int max_problems = 20;
};

/// Log times further apart than this are not one recording's [years].
constexpr double kMaxSpanYears = 100;

double rate_hz(const ChannelSummary& c) {
  if (c.count < 2 || c.last_utime <= c.first_utime) return 0.0;
  return static_cast<double>(c.count - 1) / seconds_between(c.first_utime, c.last_utime);
}

std::string type_of(const ChannelSummary& c) {
  const char* name = lcmtypes::type_name(c.fingerprint);
  std::string type = name != nullptr ? name : "unknown";
  return c.mixed_fingerprints ? type + " (mixed)" : type;
}

/// Each channel's type in the recording it was imported from (channel -> "sensor_msgs/msg/Imu"), from what the
/// import wrote on CHANNEL_SOURCES; empty for a log driftlab recorded.
using SourceTypes = std::map<std::string, std::string, std::less<>>;

SourceTypes source_types(const std::string& path, const LogSummary& s) {
  SourceTypes out;
  const auto it = std::find_if(s.channels.begin(), s.channels.end(),
                               [&](const auto& c) { return c.name == lcmtypes::kChannelSources; });
  if (it == s.channels.end()) return out;
  auto reader = LogReader::open(path, {.channels = std::string(lcmtypes::kChannelSources)});
  if (!reader || !reader->seek(it->first_utime).ok()) return out;
  Event e;
  for (int64_t n = 0; n < it->count && reader->next(e); ++n) {
    driftlab::channel_source_t m;
    if (lcmtypes::decode(e.data, m)) out[m.channel] = m.source_type;
  }
  return out;
}

std::string source_type_of(const SourceTypes& sources, const std::string& channel) {
  const auto it = sources.find(channel);
  return it == sources.end() ? std::string() : it->second;
}

nlohmann::json to_json(const std::string& path, const LogSummary& s, const SourceTypes& sources) {
  nlohmann::json channels = nlohmann::json::array();
  for (const auto& c : s.channels) {
    const char* type = lcmtypes::type_name(c.fingerprint);
    const std::string source = source_type_of(sources, c.name);
    channels.push_back({{"name", c.name},
                        {"type", type != nullptr && !c.mixed_fingerprints ? nlohmann::json(type) : nlohmann::json()},
                        {"source_type", source.empty() ? nlohmann::json() : nlohmann::json(source)},
                        {"count", c.count},
                        {"bytes", c.bytes},
                        {"rate_hz", rate_hz(c)},
                        {"first_utime", c.first_utime},
                        {"last_utime", c.last_utime},
                        {"times_back", c.times_back},
                        {"stamped", c.stamped},
                        {"stamps_repeated", c.stamps_repeated}});
  }
  nlohmann::json problems = nlohmann::json::array();
  for (const auto& p : s.problems) {
    problems.push_back({{"offset", p.offset}, {"kind", to_string(p.kind)}, {"detail", p.detail}});
  }
  return {{"file", path},
          {"bytes", s.file_bytes},
          {"events", s.events},
          {"start_utime", s.start_utime},
          {"end_utime", s.end_utime},
          {"duration_s", seconds_between(s.start_utime, s.end_utime)},
          {"channels", channels},
          {"problems", problems},
          {"problems_total", s.problems_total}};
}

void print_table(const std::string& path, const LogSummary& s, const SourceTypes& sources, int max_problems) {
  std::printf("%s: %s, %s events, %.3f s\n", path.c_str(), human_bytes(static_cast<double>(s.file_bytes)).c_str(),
              thousands(s.events).c_str(), seconds_between(s.start_utime, s.end_utime));
  if (s.events > 0) std::printf("from %s to %s\n", format_utime(s.start_utime).c_str(), format_utime(s.end_utime).c_str());
  // An imported log's channels also say their type in the recording (the ROS or PX4 type).
  size_t name_w = 7, type_w = 4, source_w = sources.empty() ? 0 : 11;
  for (const auto& c : s.channels) {
    name_w = std::max(name_w, c.name.size());
    type_w = std::max(type_w, type_of(c).size());
    if (!sources.empty()) source_w = std::max(source_w, source_type_of(sources, c.name).size());
  }
  auto source_column = [&](const std::string& text) {
    return source_w == 0 ? std::string() : "  " + text + std::string(source_w - std::min(source_w, text.size()), ' ');
  };
  if (!s.channels.empty()) {
    std::printf("\n%-*s  %-*s%s  %10s  %10s  %9s  %9s  %9s\n", static_cast<int>(name_w), "channel",
                static_cast<int>(type_w), "type", source_column("source type").c_str(), "count", "bytes", "rate Hz",
                "first s", "last s");
  }
  for (const auto& c : s.channels) {
    const std::string source = source_type_of(sources, c.name);
    std::printf("%-*s  %-*s%s  %10s  %10s  %9.2f  %9.3f  %9.3f\n", static_cast<int>(name_w), c.name.c_str(),
                static_cast<int>(type_w), type_of(c).c_str(), source_column(source.empty() ? "-" : source).c_str(),
                thousands(c.count).c_str(), human_bytes(static_cast<double>(c.bytes)).c_str(), rate_hz(c),
                seconds_between(s.start_utime, c.first_utime), seconds_between(s.start_utime, c.last_utime));
  }
  // What the index saw in time, beside the framing: log times stepping back, frozen stamps.
  std::vector<std::string> timing;
  // Log times far apart: an event stamped by a corrupt clock, or a time field overwritten (at the ends of int64_t the
  // duration and rates came out negative, and "no problems").
  constexpr double kYear = 365.25 * 86400;
  if (const double span = seconds_between(s.start_utime, s.end_utime); span > kMaxSpanYears * kYear) {
    std::string far;
    for (const auto& c : s.channels) {
      if (seconds_between(c.first_utime, c.last_utime) > kMaxSpanYears * kYear)
        far += (far.empty() ? "" : ", ") + c.name;
    }
    timing.push_back("log times span " + thousands(static_cast<int64_t>(span / kYear)) + " years (" +
                     format_utime(s.start_utime) + " to " + format_utime(s.end_utime) +
                     "): some events' times are corrupt" + (far.empty() ? "" : " (on " + far + ")"));
  }
  for (const auto& c : s.channels) {
    if (c.times_back > 0) {
      timing.push_back(c.name + ": log times step back " + thousands(c.times_back) +
                       " times (events written out of time order)");
    }
    // A fast source's clock may repeat a stamp now and then; most of them repeated means the stamps are frozen.
    if (c.stamped >= 10 && c.stamps_repeated * 2 > c.stamped) {
      timing.push_back(c.name + ": " + thousands(c.stamps_repeated) + " of " + thousands(c.stamped) +
                       " messages repeat the stamp before (frozen stamps: time cannot be told from them)");
    }
  }
  if (!timing.empty()) {
    std::printf("\ntiming (driftlab diagnose says more):\n");
    for (const auto& line : timing) std::printf("  %s\n", line.c_str());
  }
  if (s.problems_total == 0) {
    std::printf("\n%s\n", timing.empty() ? "no problems" : "no framing problems");
    return;
  }
  std::printf("\n%s problem%s:\n", thousands(static_cast<int64_t>(s.problems_total)).c_str(),
              s.problems_total == 1 ? "" : "s");
  int shown = 0;
  for (const auto& p : s.problems) {
    if (shown++ == max_problems) break;
    std::printf("  at byte %llu: %s: %s\n", static_cast<unsigned long long>(p.offset), to_string(p.kind),
                p.detail.c_str());
  }
  if (s.problems_total > static_cast<uint64_t>(max_problems)) {
    std::printf("  ... %s more (driftlab info --json lists up to %zu)\n",
                thousands(static_cast<int64_t>(s.problems_total) - max_problems).c_str(),
                LogIndex::kMaxStoredProblems);
  }
}

/// The last statistics a driftlab recorder wrote into the log (they are cumulative), if it has any.
std::optional<driftlab::recorder_stats_t> recorder_stats(const std::string& path, const LogSummary& s) {
  const std::string channel = "DRIFTLAB_RECORDER_STATS";
  const auto it = std::find_if(s.channels.begin(), s.channels.end(), [&](const auto& c) { return c.name == channel; });
  if (it == s.channels.end()) return std::nullopt;
  auto reader = LogReader::open(path, {.channels = channel});
  if (!reader || !reader->seek(it->last_utime).ok()) return std::nullopt;
  std::optional<driftlab::recorder_stats_t> last;
  Event e;
  while (reader->next(e)) {
    driftlab::recorder_stats_t stats;
    if (lcmtypes::decode(e.data, stats)) last = std::move(stats);
  }
  return last;
}

nlohmann::json recorder_json(const driftlab::recorder_stats_t& r) {
  return {{"received", r.received},         {"written", r.written},
          {"lost", r.lost},                 {"kernel_dropped", r.kernel_dropped},
          {"queue_dropped", r.queue_dropped}, {"fragments_incomplete", r.fragments_incomplete},
          {"garbage_datagrams", r.garbage_datagrams}, {"senders", r.nsenders}};
}

int run_info(const InfoOptions& o) {
  Progress progress("scanning " + o.log);
  auto index = LogIndex::load_or_build(o.log, [&](uint64_t done, uint64_t total) { progress.update(done, total); });
  if (!index) return fail(index.error().message);
  const LogSummary& s = index->summary();
  if (s.events == 0 && s.file_bytes > 0 && !s.problems.empty() && s.problems.front().offset == 0 &&
      s.problems.front().kind == ProblemKind::kGarbage) {
    return fail(not_an_event_log(o.log, s.file_bytes));
  }
  const auto recorded = recorder_stats(o.log, s);
  const SourceTypes sources = source_types(o.log, s);
  // A PX4 flight log's time of day, from its GNSS receiver (ULOG_UTC: the import writes it).
  const bool has_utc = std::any_of(s.channels.begin(), s.channels.end(),
                                   [](const auto& c) { return c.name == formats::kUlogUtcChannel; });
  const analyzers::FlightUtc utc = has_utc ? analyzers::flight_utc(o.log, s.start_utime) : analyzers::FlightUtc{};
  if (o.json.wanted()) {
    auto j = to_json(o.log, s, sources);
    if (recorded) j["recorder"] = recorder_json(*recorded);
    if (utc.known) j["utc"] = analyzers::flight_utc_json(utc);
    if (!o.json.emit(j.dump(2) + "\n")) return kExitFailure;
  }
  if (!o.json.print) {
    print_table(o.log, s, sources, o.max_problems);
    if (utc.known) std::printf("\n%s\n", analyzers::flight_utc_line(utc).c_str());
    if (recorded) {
      const auto& r = *recorded;
      std::printf("\nrecorded by driftlab record: %s messages received from %d sender%s; lost %s (sequence gaps), "
                  "%s dropped by the kernel, %s by the recorder's queue, %s fragmented messages incomplete\n",
                  thousands(r.received).c_str(), r.nsenders, r.nsenders == 1 ? "" : "s", thousands(r.lost).c_str(),
                  thousands(r.kernel_dropped).c_str(), thousands(r.queue_dropped).c_str(),
                  thousands(r.fragments_incomplete).c_str());
    }
  }
  return kExitOk;
}

}  // namespace

void add_info_command(CLI::App& app, int* exit_code) {
  auto opts = std::make_shared<InfoOptions>();
  CLI::App* cmd = app.add_subcommand("info", "Summarise a log: channels, message types, rates, time range and problems.");
  cmd->add_option("log", opts->inputs, kLogInputHelp)->required();
  add_json_options(cmd, &opts->json, "the summary");
  cmd->add_option("--max-problems", opts->max_problems, "Problems listed in the table")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9)));
  cmd->callback([opts, exit_code] {
    auto log = recordings::log_for(opts->inputs);
    if (!log) {
      *exit_code = fail(log.error().message, exit_code_for_input(log.error()));
      return;
    }
    opts->log = *log;
    std::vector<std::string> inputs = opts->inputs;
    inputs.push_back(opts->log);  // and its conversion
    if (Status s = opts->json.check(inputs); !s) {
      *exit_code = fail(s.message());
      return;
    }
    *exit_code = run_info(*opts);
  });
}

}  // namespace driftlab::apps
