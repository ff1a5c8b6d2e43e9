// Child processes: start one, wait for it, or both; a plotting script run with the Python that has matplotlib. Used by
// the commands that run other driftlab commands (demo, report's plotting, sweeps and batches). Thread-safety: the
// functions are; a pid belongs to whoever started it.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab {

/// Starts argv[0] (looked up in PATH) with argv; its standard output and error go to the files given (truncated,
/// created 0644), else to ours. Returns its pid, or -1 when it cannot be started.
pid_t start_process(const std::vector<std::string>& argv, const std::string& stdout_path,
                    const std::string& stderr_path = "");

/// The exit code a shell would give for a waitpid status: the code, or 128 + N when signal N ended the process.
int exit_code_of(int wait_status);

/// Waits for pid (retrying on EINTR) and returns its exit code as exit_code_of says; 127 when waiting fails.
int wait_process(pid_t pid);

/// start_process, then wait_process: 127 when it could not be started.
int run_process(const std::vector<std::string>& argv, const std::string& stdout_path,
                const std::string& stderr_path = "");

/// The last non-empty line of a file: what a child process said last on the standard error it was given.
std::string last_line_of(const std::string& path);

/// Runs a plotting script (Python source compiled into the program) as `python3 SCRIPT ARGS...`: written to
/// DIR/.NAME, run with the first Python that has matplotlib ($DRIFTLAB_PYTHON, python3 on PATH, Debian's
/// /usr/bin/python3: the script exits 3 without matplotlib), then removed. Errors: no such Python, or the script's
/// exit code.
Status run_plot_script(const char* script, const std::string& name, const std::string& dir,
                       const std::vector<std::string>& args);

}  // namespace driftlab
