// The driftlab subcommands. Each add_*_command registers a subcommand on app; when it runs, its exit
// code is stored in *exit_code (0 ok, 1 failure while working, 2 bad usage or bad input).
//
// `driftlab` itself holds the commands that need no simulator, SLAM or vision library (info, diagnose, recover,
// eval, export tum/csv, record, report, demo), so they start in milliseconds. The others live in programs of their own
// (driftlab-sim, driftlab-replay, driftlab-rawlog; installed, in PREFIX/lib/driftlab) and `driftlab` runs them, as git
// runs git-* programs: `driftlab replay ...` is `driftlab-replay replay ...`. kTools lists them; architecture.md: why.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace CLI {
class App;
}

namespace driftlab::apps {

void add_info_command(CLI::App& app, int* exit_code);
void add_eval_command(CLI::App& app, int* exit_code);
void add_record_command(CLI::App& app, int* exit_code);
void add_diagnose_command(CLI::App& app, int* exit_code);
void add_recover_command(CLI::App& app, int* exit_code);
void add_report_command(CLI::App& app, int* exit_code);
void add_demo_command(CLI::App& app, int* exit_code);
/// sweep SPEC, sweep status|collect, and batch diagnose|eval|report (apps/sweep_main.cc, batch/).
void add_sweep_command(CLI::App& app, int* exit_code);
void add_batch_command(CLI::App& app, int* exit_code);
/// import FILE (ROS 1 bags, CARMEN logs; MRPT rawlogs handed to driftlab-rawlog), on the `import` subcommand.
void add_import_file_command(CLI::App& import_command, int* exit_code);
/// export tum, export csv, on the `export` subcommand.
void add_export_commands(CLI::App& export_command, int* exit_code);
/// export mcap, export rosbag2 (ROS 2 bags in MCAP storage), on the `export` subcommand.
void add_export_mcap_commands(CLI::App& export_command, int* exit_code);

// In programs of their own:
void add_sim_command(CLI::App& app, int* exit_code);                 // driftlab-sim
void add_replay_command(CLI::App& app, int* exit_code);              // driftlab-replay
void add_run_command(CLI::App& app, int* exit_code);                 // driftlab-replay
/// import rawlog and export rawlog, on the `import` and `export` subcommands (driftlab-rawlog).
void add_rawlog_commands(CLI::App& import_command, CLI::App& export_command, int* exit_code);

/// A command that runs in a program of its own: `word` (and `sub`, for `import rawlog`) on the command line.
struct ToolCommand {
  const char* word;
  const char* sub;  ///< nullptr: any
  const char* program;
  const char* description;
};
/// The description of a tool command, for its own --help and for the dispatcher's.
const char* tool_description(const char* word, const char* sub = nullptr);

/// The tool command argv asks for, or nullptr.
const ToolCommand* find_tool(int argc, char** argv);
/// Runs the tool's program with argv: from the folder of the running program or the install tree's lib/driftlab
/// (core/install_layout.h), else from PATH. Returns only when
/// it cannot be started (one line on stderr, exit code 1).
int exec_tool(const ToolCommand& tool, char** argv);

/// Parses argv with app and returns the exit code: the command's, or CLI11's for --help/--version, or 2 (one
/// line) for a usage error.
int parse_and_run(CLI::App& app, int argc, char** argv, const int& exit_code);

/// --help-config on cmd: calls print (the reference of the config files the command reads, from their tables) and
/// exits with 0, before any other option is checked.
void add_config_help(CLI::App& cmd, void (*print)());

/// The `import` and `export` parent commands.
CLI::App& add_import_command(CLI::App& app);
CLI::App& add_export_command(CLI::App& app);

}  // namespace driftlab::apps
