// The programs that hold driftlab's heavy commands (driftlab-sim, driftlab-replay, driftlab-rawlog), built from
// this file with DRIFTLAB_TOOL set. `driftlab` runs them; run directly they behave the same:
// `driftlab-replay replay LOG ...`.
#include <CLI/CLI.hpp>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "apps/cli_util.h"
#include "apps/commands.h"

int main(int argc, char** argv) {
  using namespace driftlab::apps;
  CLI::App app{"driftlab: record, replay and diagnose robot logs (LCM event logs).", "driftlab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(DRIFTLAB_VERSION));
  app.get_formatter()->column_width(36);
  int exit_code = kExitOk;
#if DRIFTLAB_TOOL == 1
  add_sim_command(app, &exit_code);
#elif DRIFTLAB_TOOL == 2
#if defined(__GLIBC__)
  // The modules allocate and free large workspaces over and over (the 2D SLAM's optimiser and its sparse
  // Cholesky at every loop closure, the far loop search's grids): with glibc's default 128 kB of padding the heap
  // is grown and trimmed back each time and every page faulted in again. 64 MB of padding keeps them (only pages
  // touched are resident): Intel's SLAM replay on one core 7.1 -> 6.5 s, its peak memory the same.
  mallopt(M_TOP_PAD, 64 << 20);
#endif
  add_replay_command(app, &exit_code);
  add_run_command(app, &exit_code);
#elif DRIFTLAB_TOOL == 3
  add_rawlog_commands(add_import_command(app), add_export_command(app), &exit_code);
#else
#error "DRIFTLAB_TOOL: 1 (sim), 2 (replay, run) or 3 (rawlog)"
#endif
  return parse_and_run(app, argc, argv, exit_code);
}
