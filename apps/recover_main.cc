// driftlab recover LOG -o CLEAN: every intact event of a damaged log into a clean one, and a list of what was left
// out, so the clean file can go to tools that stop at the first bad byte (lcm-logplayer, LCM's own readers), as
// `mcap recover` does for MCAP files.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <map>
#include <memory>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/log_format.h"
#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "lcmtypes/validate.h"

namespace driftlab::apps {
namespace {

struct RecoverOptions {
  std::string log, out;
  bool keep_malformed = false;
  JsonOutput json;
  int max_problems = 20;
};

struct Malformed {
  int64_t count = 0;
  std::string first;  ///< why the first one was left out
};

int run_recover(const RecoverOptions& o) {
  if (Status s = refuse_same_file(o.out, {o.log}); !s) return fail(s.message());
  if (Status s = o.json.check({o.log}, {o.out}); !s) return fail(s.message());
  if (Status s = check_event_log(o.log); !s) return fail(s.message());
  std::vector<Problem> problems;
  auto reader = LogReader::open(o.log, {.on_problem = [&](const Problem& p) {
                                  if (problems.size() < LogIndex::kMaxStoredProblems) problems.push_back(p);
                                }});
  if (!reader) return fail(reader.error().message);
  auto writer = LogWriter::create(o.out, {.atomic = true});
  if (!writer) return fail(writer.error().message, kExitFailure);
  Progress progress("recovering " + o.log);
  std::map<std::string, Malformed, std::less<>> malformed;
  uint64_t kept_bytes = 0, intact_bytes = 0;  // of the events written; of every intact event
  Event e;
  int64_t long_channels = 0;
  while (reader->next(e)) {
    progress.update(reader->position(), reader->size_bytes());
    const uint64_t event_bytes = logfmt::kEventHeaderSize + e.channel.size() + e.data.size();
    intact_bytes += event_bytes;
    // The reader takes channel names up to 1023 bytes; LCM's tools (and our writer) stop at 255.
    if (e.channel.size() > static_cast<size_t>(logfmt::kMaxWriteChannelLength)) {
      ++long_channels;
      continue;
    }
    // Messages of a driftlab type that lie about their lengths would make other tools' decoders throw.
    if (!o.keep_malformed) {
      if (const auto why = lcmtypes::layout_problem(e.data)) {
        auto [it, fresh] = malformed.try_emplace(std::string(e.channel));
        if (fresh) it->second.first = "event at byte " + std::to_string(e.offset) + ": " + *why;
        ++it->second.count;
        continue;
      }
    }
    if (Status s = writer->write(e.utime, e.channel, e.data); !s) {
      writer->discard();
      return fail(s.message(), kExitFailure);
    }
    kept_bytes += event_bytes;
  }
  if (Status s = writer->close(); !s) return fail(s.message(), kExitFailure);

  const uint64_t total = reader->size_bytes();
  int64_t dropped_messages = 0;
  for (const auto& [channel, m] : malformed) dropped_messages += m.count;
  if (o.json.wanted()) {
    nlohmann::json j;
    j["log"] = o.log;
    j["out"] = o.out;
    j["events"] = writer->events();
    j["bytes_in"] = total;
    j["bytes_out"] = kept_bytes;
    j["bytes_damaged"] = total - intact_bytes;
    j["problems_total"] = reader->problems();
    j["long_channels"] = long_channels;
    j["problems"] = nlohmann::json::array();
    for (const auto& p : problems) {
      j["problems"].push_back({{"offset", p.offset}, {"kind", to_string(p.kind)}, {"detail", p.detail}});
    }
    j["malformed"] = nlohmann::json::object();
    for (const auto& [channel, m] : malformed) j["malformed"][channel] = {{"count", m.count}, {"first", m.first}};
    if (!o.json.emit(j.dump(2) + "\n")) return kExitFailure;
    if (o.json.print) return kExitOk;
  }
  std::printf("%s -> %s: %s events, %s of %s\n", o.log.c_str(), o.out.c_str(), thousands(writer->events()).c_str(),
              human_bytes(static_cast<double>(kept_bytes)).c_str(), human_bytes(static_cast<double>(total)).c_str());
  if (reader->problems() == 0 && malformed.empty() && long_channels == 0) {
    std::printf("nothing left out: the log was intact\n");
    return kExitOk;
  }
  if (reader->problems() > 0) {
    std::printf("\nleft out %s damaged bytes at %s spot%s:\n",
                thousands(static_cast<int64_t>(total - intact_bytes)).c_str(),
                thousands(static_cast<int64_t>(reader->problems())).c_str(), reader->problems() == 1 ? "" : "s");
    int shown = 0;
    for (const auto& p : problems) {
      if (shown++ == o.max_problems) break;
      std::printf("  at byte %llu: %s: %s\n", static_cast<unsigned long long>(p.offset), to_string(p.kind),
                  p.detail.c_str());
    }
    if (reader->problems() > static_cast<uint64_t>(o.max_problems)) {
      std::printf("  ... %s more (--json lists up to %zu)\n",
                  thousands(static_cast<int64_t>(reader->problems()) - o.max_problems).c_str(),
                  LogIndex::kMaxStoredProblems);
    }
  }
  if (long_channels > 0) {
    std::printf(
        "\nleft out %s intact events on channels named with more than %d bytes, which LCM's tools cannot "
        "take\n",
        thousands(long_channels).c_str(), logfmt::kMaxWriteChannelLength);
  }
  if (!malformed.empty()) {
    std::printf(
        "\nleft out %s intact events whose message does not hold its type's layout (--keep-malformed keeps "
        "them):\n",
        thousands(dropped_messages).c_str());
    for (const auto& [channel, m] : malformed) {
      std::printf("  %s: %s (first: %s)\n", channel.c_str(), thousands(m.count).c_str(), m.first.c_str());
    }
  }
  return kExitOk;
}

}  // namespace

void add_recover_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<RecoverOptions>();
  CLI::App* cmd = app.add_subcommand(
      "recover", "Write every intact event of a damaged log into a clean one, and list what was left out.");
  cmd->footer(
      "Reads past damage as every driftlab command does (resuming at the next event) and writes what it reads, in\n"
      "file order with the same log times, as a log any LCM tool reads to the end; event numbers count from 0\n"
      "again. Left out: damaged bytes (listed with their offsets, as `driftlab info` shows them), events on\n"
      "channels named with more than 255 bytes and, unless --keep-malformed, messages of a driftlab type that do\n"
      "not hold their type's layout. OUT is written beside and renamed when complete.");
  cmd->add_option("log", o->log, "Damaged LCM event log")->required();
  cmd->add_option("-o,--out", o->out, "Clean log to write")->required();
  cmd->add_flag("--keep-malformed", o->keep_malformed, "Keep intact events whose message is malformed for its type");
  add_json_options(cmd, &o->json, "a summary");
  cmd->add_option("--max-problems", o->max_problems, "Damaged spots listed in the text")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9)));
  cmd->callback([o, exit_code] { *exit_code = run_recover(*o); });
}

}  // namespace driftlab::apps
