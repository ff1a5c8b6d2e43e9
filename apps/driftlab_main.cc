// The driftlab command: one program, one subcommand per tool.
#include <CLI/CLI.hpp>

#include "apps/cli_util.h"
#include "apps/commands.h"

int main(int argc, char** argv) {
  CLI::App app{"driftlab: record, replay and diagnose robot logs (LCM event logs).", "driftlab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(DRIFTLAB_VERSION));
  app.get_formatter()->column_width(36);
  int exit_code = driftlab::apps::kExitOk;
  driftlab::apps::add_info_command(app, &exit_code);
  driftlab::apps::add_eval_command(app, &exit_code);
  driftlab::apps::add_record_command(app, &exit_code);
  driftlab::apps::add_diagnose_command(app, &exit_code);
  driftlab::apps::add_sim_command(app, &exit_code);
  driftlab::apps::add_replay_command(app, &exit_code);
  driftlab::apps::add_run_command(app, &exit_code);
  driftlab::apps::add_rawlog_commands(app, &exit_code);
  driftlab::apps::add_report_command(app, &exit_code);
  driftlab::apps::add_demo_command(app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line naming the problem, then where to look; exit 2 like other usage errors.
    return driftlab::apps::fail(std::string(e.what()) + " (see 'driftlab --help')");
  }
  return exit_code;
}
