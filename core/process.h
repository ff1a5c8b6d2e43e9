// Child processes: start one, wait for it, or both. Used by the commands that run other driftlab commands (demo,
// report's plotting, sweeps and batches). Thread-safety: the functions are; a pid belongs to whoever started it.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

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

}  // namespace driftlab
