// driftlab info LOG [--json]: what a log holds (channels, types, rates, time range) and what is wrong with it.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <memory>

#include "analyzers/log_info.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/progress_line.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

struct InfoOptions {
  std::vector<std::string> inputs;
  std::string log;
  JsonOutput json;
  int max_problems = 20;
};

int run_info(const InfoOptions& o) {
  Progress progress("scanning " + o.log);
  auto info = analyzers::log_info(o.log, [&](uint64_t done, uint64_t total) { progress.update(done, total); });
  if (!info) return fail(info.error().message);
  if (o.json.wanted() && !o.json.emit(to_json(*info).dump(2) + "\n")) return kExitFailure;
  if (!o.json.print) std::fputs(analyzers::log_info_text(*info, o.max_problems).c_str(), stdout);
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
      *exit_code = fail(log.error().message, exit_code_for(log.error()));
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
