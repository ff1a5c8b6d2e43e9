// The driftlab subcommands. Each add_*_command registers a subcommand on app; when it runs, its exit
// code is stored in *exit_code (0 ok, 1 failure while working, 2 bad usage or bad input).
#pragma once

namespace CLI {
class App;
}

namespace driftlab::apps {

void add_info_command(CLI::App& app, int* exit_code);
void add_eval_command(CLI::App& app, int* exit_code);
void add_record_command(CLI::App& app, int* exit_code);
void add_diagnose_command(CLI::App& app, int* exit_code);
void add_sim_command(CLI::App& app, int* exit_code);
void add_replay_command(CLI::App& app, int* exit_code);
void add_run_command(CLI::App& app, int* exit_code);
void add_report_command(CLI::App& app, int* exit_code);
void add_demo_command(CLI::App& app, int* exit_code);
void add_rawlog_commands(CLI::App& app, int* exit_code);  // import rawlog, export rawlog (and what follows)
/// export tum, export csv: added to the `export` subcommand that add_rawlog_commands creates.
void add_export_commands(CLI::App& export_command, int* exit_code);

}  // namespace driftlab::apps
