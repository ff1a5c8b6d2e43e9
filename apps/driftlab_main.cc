// The driftlab command: the light subcommands in this program, the heavy ones (simulation, replay with SLAM, MRPT
// rawlogs) run from programs of their own beside it (apps/commands.h).
#include <CLI/CLI.hpp>

#include "apps/cli_util.h"
#include "apps/commands.h"

int main(int argc, char** argv) {
  using namespace driftlab::apps;
  if (const ToolCommand* tool = find_tool(argc, argv)) return exec_tool(*tool, argv);

  CLI::App app{"driftlab: record, replay and diagnose robot logs (LCM event logs).", "driftlab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(DRIFTLAB_VERSION));
  app.get_formatter()->column_width(36);
  int exit_code = kExitOk;
  add_info_command(app, &exit_code);
  add_eval_command(app, &exit_code);
  add_record_command(app, &exit_code);
  add_diagnose_command(app, &exit_code);
  add_recover_command(app, &exit_code);
  // Listed here for --help, run by their own programs (find_tool above takes them before parsing).
  for (const char* word : {"sim", "replay", "run"}) app.add_subcommand(word, tool_description(word))->allow_extras();
  CLI::App& import = add_import_command(app);
  CLI::App& exp = add_export_command(app);
  import.add_subcommand("rawlog", tool_description("import", "rawlog"))->allow_extras();
  exp.add_subcommand("rawlog", tool_description("export", "rawlog"))->allow_extras();
  add_report_command(app, &exit_code);
  add_demo_command(app, &exit_code);
  add_sweep_command(app, &exit_code);
  add_batch_command(app, &exit_code);
  add_export_commands(exp, &exit_code);
  add_export_mcap_commands(exp, &exit_code);
  add_import_file_command(import, &exit_code);
  return parse_and_run(app, argc, argv, exit_code);
}
