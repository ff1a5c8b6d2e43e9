// driftlab record: capture live LCM traffic to a log without loss, recording where anything was lost.
#include <CLI/CLI.hpp>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <ctime>
#include <memory>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/same_file.h"
#include "core/wall_clock.h"
#include "recorder/recorder.h"

namespace driftlab::apps {
namespace {

std::atomic<recorder::Recorder*> g_recorder{nullptr};

void on_signal(int) {
  if (auto* r = g_recorder.load()) r->request_stop();
}

std::string default_out(const WallClock& clock) {
  const auto now = static_cast<time_t>(clock.now().us() / 1000000);  // [s since the epoch]
  std::tm tm{};
  localtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof(buf), "record-%Y%m%d-%H%M%S.lcm", &tm);
  return buf;
}

int run_record(recorder::RecordOptions o) {
  if (Status s = recorder::check_options(o); !s) return fail(s.message());
  const SystemWallClock clock;
  if (o.out.empty()) o.out = default_out(clock);
  // The log is written beside its path and renamed into place: a FIFO or device there would be replaced.
  if (Status s = refuse_same_file(o.out, {}); !s) return fail(s.message());
  const bool tty = isatty(STDERR_FILENO) == 1;
  if (tty) o.on_status = [](const std::string& line) { std::fprintf(stderr, "\r\033[K%s", line.c_str()); };
  // What it listens to, once it does: on stderr, so standard output keeps only the summary.
  o.on_listening = [&o] { std::fputs(recorder::listening_line(o).c_str(), stderr); };
  recorder::Recorder rec(o, clock);
  g_recorder.store(&rec);
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  auto result = rec.run();
  g_recorder.store(nullptr);
  if (tty) std::fprintf(stderr, "\r\033[K");
  if (!result) return fail(result.error().message, kExitFailure);
  std::fputs(recorder::record_text(*result).c_str(), stdout);
  return kExitOk;
}

}  // namespace

void add_record_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<recorder::RecordOptions>();
  CLI::App* cmd = app.add_subcommand(
      "record", "Record live LCM traffic to a log without loss; losses are counted and written into the log.");
  cmd->footer(
      "Stops on Ctrl-C or SIGTERM, closing the log cleanly. Every --flush-interval the log is synced to disk, so a\n"
      "crash or power cut loses at most that much. Statistics (driftlab.recorder_stats_t) go to --stats-channel.");
  cmd->add_option("--url", o->url, "LCM URL to listen on")->capture_default_str();
  cmd->add_option("-o,--out", o->out, "Log file (default: record-YYYYMMDD-HHMMSS.lcm)");
  cmd->add_option("-c,--channels", o->channels, "Record channels fully matching this regex")->capture_default_str();
  cmd->add_option("--exclude", o->exclude, "Leave out channels fully matching this regex");
  cmd->add_option("--split-mb", o->split_mb, "Start a new file past this many MB (0: never)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9), "MB"));
  cmd->add_option("--split-s", o->split_s, "Start a new file after this many seconds (0: never)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e7), "s"));
  cmd->add_option("--duration", o->duration_s, "Stop after this many seconds (0: until stopped)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e7), "s"));
  cmd->add_option("--flush-interval", o->flush_interval_s, "Sync the log to disk this often [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 3600), "s"));
  cmd->add_option("--stats-interval", o->stats_interval_s, "Write the statistics channel this often [s]")
      ->capture_default_str()
      ->check(in_range(config::above(0, 3600), "s"));
  cmd->add_option("--stats-channel", o->stats_channel, "Channel of the recorder's statistics")->capture_default_str();
  cmd->add_option("--queue-bytes", o->queue_max_bytes, "Memory for messages waiting for the disk [bytes]")
      ->capture_default_str()
      ->check(in_range(config::between(1, 1099511627776.0), "bytes"));
  cmd->callback([o, exit_code] { *exit_code = run_record(*o); });
}

}  // namespace driftlab::apps
