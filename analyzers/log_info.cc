#include "analyzers/log_info.h"

#include <algorithm>
#include <cstdio>

#include "analyzers/diagnosis_json.h"
#include "analyzers/diagnosis_text.h"
#include "core/log_reader.h"
#include "core/number_text.h"
#include "core/time.h"
#include "core/wall_clock.h"
#include "driftlab/channel_source_t.hpp"
#include "formats/ulog_messages.h"
#include "lcmtypes/seq_origin.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

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

nlohmann::json summary_json(const std::string& path, const LogSummary& s, const SourceTypes& sources) {
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

void table_text(std::string& out, const std::string& path, const LogSummary& s, const SourceTypes& sources,
                int max_problems) {
  appendf(out, "%s: %s, %s events, %.3f s\n", path.c_str(), human_bytes(static_cast<double>(s.file_bytes)).c_str(),
          thousands(s.events).c_str(), seconds_between(s.start_utime, s.end_utime));
  if (s.events > 0)
    appendf(out, "from %s to %s\n", format_utime(s.start_utime).c_str(), format_utime(s.end_utime).c_str());
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
    appendf(out, "\n%-*s  %-*s%s  %10s  %10s  %9s  %9s  %9s\n", static_cast<int>(name_w), "channel",
            static_cast<int>(type_w), "type", source_column("source type").c_str(), "count", "bytes", "rate Hz",
            "first s", "last s");
  }
  for (const auto& c : s.channels) {
    const std::string source = source_type_of(sources, c.name);
    appendf(out, "%-*s  %-*s%s  %10s  %10s  %9.2f  %9.3f  %9.3f\n", static_cast<int>(name_w), c.name.c_str(),
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
    appendf(out, "\ntiming (driftlab diagnose says more):\n");
    for (const auto& line : timing) appendf(out, "  %s\n", line.c_str());
  }
  if (s.problems_total == 0) {
    appendf(out, "\n%s\n", timing.empty() ? "no problems" : "no framing problems");
    return;
  }
  appendf(out, "\n%s problem%s:\n", thousands(static_cast<int64_t>(s.problems_total)).c_str(),
          s.problems_total == 1 ? "" : "s");
  int shown = 0;
  for (const auto& p : s.problems) {
    if (shown++ == max_problems) break;
    appendf(out, "  at byte %llu: %s: %s\n", static_cast<unsigned long long>(p.offset), to_string(p.kind),
            p.detail.c_str());
  }
  if (s.problems_total > static_cast<uint64_t>(max_problems)) {
    appendf(out, "  ... %s more (driftlab info --json lists up to %zu)\n",
            thousands(static_cast<int64_t>(s.problems_total) - max_problems).c_str(), LogIndex::kMaxStoredProblems);
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
  return {{"received", r.received},
          {"written", r.written},
          {"lost", r.lost},
          {"kernel_dropped", r.kernel_dropped},
          {"queue_dropped", r.queue_dropped},
          {"fragments_incomplete", r.fragments_incomplete},
          {"garbage_datagrams", r.garbage_datagrams},
          {"senders", r.nsenders}};
}

}  // namespace

Result<LogInfo> log_info(const std::string& path, const std::function<void(uint64_t, uint64_t)>& progress) {
  // The channels' stamp counts: read by the message layer's word on which types carry a stream header.
  const HeaderReader headers = [](std::span<const uint8_t> data, int64_t utime) -> std::optional<HeaderFields> {
    const auto h = lcmtypes::read_header(data, utime);
    if (!h) return std::nullopt;
    return HeaderFields{h->seq, h->utime};
  };
  auto index = LogIndex::load_or_build(path, progress, LogIndex::kDefaultCacheMinBytes, headers);
  if (!index) return index.error();
  LogInfo info;
  info.path = path;
  info.summary = index->summary();
  const LogSummary& s = info.summary;
  if (s.events == 0 && s.file_bytes > 0 && !s.problems.empty() && s.problems.front().offset == 0 &&
      s.problems.front().kind == ProblemKind::kGarbage) {
    return Error{not_an_event_log(path, s.file_bytes)};
  }
  info.recorder = recorder_stats(path, s);
  info.source_types = source_types(path, s);
  if (std::any_of(s.channels.begin(), s.channels.end(),
                  [](const auto& c) { return c.name == formats::kUlogUtcChannel; })) {
    info.utc = flight_utc(path, s.start_utime);
  }
  return info;
}

nlohmann::json to_json(const LogInfo& info) {
  nlohmann::json j = summary_json(info.path, info.summary, info.source_types);
  if (info.recorder) j["recorder"] = recorder_json(*info.recorder);
  if (info.utc.known) j["utc"] = flight_utc_json(info.utc);
  return j;
}

std::string log_info_text(const LogInfo& info, int max_problems) {
  std::string out;
  table_text(out, info.path, info.summary, info.source_types, max_problems);
  if (info.utc.known) out += "\n" + flight_utc_line(info.utc) + "\n";
  if (info.recorder) {
    const auto& r = *info.recorder;
    appendf(out,
            "\nrecorded by driftlab record: %s messages received from %d sender%s; lost %s (sequence gaps), "
            "%s dropped by the kernel, %s by the recorder's queue, %s fragmented messages incomplete\n",
            thousands(r.received).c_str(), r.nsenders, r.nsenders == 1 ? "" : "s", thousands(r.lost).c_str(),
            thousands(r.kernel_dropped).c_str(), thousands(r.queue_dropped).c_str(),
            thousands(r.fragments_incomplete).c_str());
  }
  return out;
}

}  // namespace driftlab::analyzers
