#include "recorder/recover.h"

#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "core/number_text.h"
#include "lcmtypes/validate.h"

namespace driftlab::recorder {

Result<Recovery> recover_log(const std::string& log, const std::string& out, const RecoverOptions& options) {
  Recovery r;
  r.log = log;
  r.out = out;
  if (Status s = check_event_log(log); !s) return s.error();
  auto reader = LogReader::open(log, {.on_problem = [&r](const Problem& p) {
                                  if (r.problems.size() < LogIndex::kMaxStoredProblems) r.problems.push_back(p);
                                }});
  if (!reader) return reader.error();
  auto writer = LogWriter::create(out, {.atomic = true});
  if (!writer) return writer.error();
  uint64_t intact_bytes = 0;  // of every intact event
  Event e;
  while (reader->next(e)) {
    if (options.progress) options.progress(reader->position(), reader->size_bytes());
    const uint64_t event_bytes = logfmt::kEventHeaderSize + e.channel.size() + e.data.size();
    intact_bytes += event_bytes;
    // The reader takes channel names up to 1023 bytes; LCM's tools (and our writer) stop at 255.
    if (e.channel.size() > static_cast<size_t>(logfmt::kMaxWriteChannelLength)) {
      ++r.long_channels;
      continue;
    }
    if (!options.keep_malformed) {
      if (const auto why = lcmtypes::layout_problem(e.data)) {
        auto [it, fresh] = r.malformed.try_emplace(std::string(e.channel));
        if (fresh) it->second.first = "event at byte " + std::to_string(e.offset) + ": " + *why;
        ++it->second.count;
        continue;
      }
    }
    if (Status s = writer->write(e.utime, e.channel, e.data); !s) {
      writer->discard();
      return s.error();
    }
    r.bytes_out += event_bytes;
  }
  if (Status s = writer->close(); !s) return s.error();
  r.events = writer->events();
  r.bytes_in = reader->size_bytes();
  r.bytes_damaged = r.bytes_in - intact_bytes;
  r.problems_total = reader->problems();
  return r;
}

nlohmann::json to_json(const Recovery& r) {
  nlohmann::json j;
  j["log"] = r.log;
  j["out"] = r.out;
  j["events"] = r.events;
  j["bytes_in"] = r.bytes_in;
  j["bytes_out"] = r.bytes_out;
  j["bytes_damaged"] = r.bytes_damaged;
  j["problems_total"] = r.problems_total;
  j["long_channels"] = r.long_channels;
  j["problems"] = nlohmann::json::array();
  for (const auto& p : r.problems) {
    j["problems"].push_back({{"offset", p.offset}, {"kind", to_string(p.kind)}, {"detail", p.detail}});
  }
  j["malformed"] = nlohmann::json::object();
  for (const auto& [channel, m] : r.malformed) j["malformed"][channel] = {{"count", m.count}, {"first", m.first}};
  return j;
}

std::string recovery_text(const Recovery& r, int max_problems) {
  std::string out;
  appendf(out, "%s -> %s: %s events, %s of %s\n", r.log.c_str(), r.out.c_str(), thousands(r.events).c_str(),
          human_bytes(static_cast<double>(r.bytes_out)).c_str(), human_bytes(static_cast<double>(r.bytes_in)).c_str());
  if (r.problems_total == 0 && r.malformed.empty() && r.long_channels == 0) {
    return out + "nothing left out: the log was intact\n";
  }
  if (r.problems_total > 0) {
    appendf(out, "\nleft out %s damaged bytes at %s spot%s:\n",
            thousands(static_cast<int64_t>(r.bytes_damaged)).c_str(),
            thousands(static_cast<int64_t>(r.problems_total)).c_str(), r.problems_total == 1 ? "" : "s");
    int shown = 0;
    for (const auto& p : r.problems) {
      if (shown++ == max_problems) break;
      appendf(out, "  at byte %llu: %s: %s\n", static_cast<unsigned long long>(p.offset), to_string(p.kind),
              p.detail.c_str());
    }
    if (r.problems_total > static_cast<uint64_t>(max_problems)) {
      appendf(out, "  ... %s more (--json lists up to %zu)\n",
              thousands(static_cast<int64_t>(r.problems_total) - max_problems).c_str(), LogIndex::kMaxStoredProblems);
    }
  }
  if (r.long_channels > 0) {
    appendf(out,
            "\nleft out %s intact events on channels named with more than %d bytes, which LCM's tools cannot take\n",
            thousands(r.long_channels).c_str(), logfmt::kMaxWriteChannelLength);
  }
  if (!r.malformed.empty()) {
    int64_t dropped = 0;
    for (const auto& [channel, m] : r.malformed) dropped += m.count;
    appendf(out,
            "\nleft out %s intact events whose message does not hold its type's layout (--keep-malformed keeps "
            "them):\n",
            thousands(dropped).c_str());
    for (const auto& [channel, m] : r.malformed) {
      appendf(out, "  %s: %s (first: %s)\n", channel.c_str(), thousands(m.count).c_str(), m.first.c_str());
    }
  }
  return out;
}

}  // namespace driftlab::recorder
