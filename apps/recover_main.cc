// driftlab recover LOG -o CLEAN: every intact event of a damaged log into a clean one, and a list of what was left
// out, so the clean file can go to tools that stop at the first bad byte (lcm-logplayer, LCM's own readers), as
// `mcap recover` does for MCAP files.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/progress_line.h"
#include "core/same_file.h"
#include "recorder/recover.h"

namespace driftlab::apps {
namespace {

struct RecoverArgs {
  std::string log, out;
  recorder::RecoverOptions options;
  JsonOutput json;
  int max_problems = 20;
};

int run_recover(const RecoverArgs& a) {
  if (Status s = refuse_same_file(a.out, {a.log}); !s) return fail(s.message());
  if (Status s = a.json.check({a.log}, {a.out}); !s) return fail(s.message());
  Progress progress("recovering " + a.log);
  recorder::RecoverOptions options = a.options;
  options.progress = [&progress](uint64_t done, uint64_t total) { progress.update(done, total); };
  auto r = recorder::recover_log(a.log, a.out, options);
  progress.finish();
  if (!r) return fail(r.error().message, exit_code_for(r.error()));
  if (a.json.wanted()) {
    if (!a.json.emit(to_json(*r).dump(2) + "\n")) return kExitFailure;
    if (a.json.print) return kExitOk;
  }
  std::fputs(recorder::recovery_text(*r, a.max_problems).c_str(), stdout);
  return kExitOk;
}

}  // namespace

void add_recover_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<RecoverArgs>();
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
  cmd->add_flag("--keep-malformed", o->options.keep_malformed,
                "Keep intact events whose message is malformed for its type");
  add_json_options(cmd, &o->json, "a summary");
  cmd->add_option("--max-problems", o->max_problems, "Damaged spots listed in the text")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9)));
  cmd->callback([o, exit_code] { *exit_code = run_recover(*o); });
}

}  // namespace driftlab::apps
