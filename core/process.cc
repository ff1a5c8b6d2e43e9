#include "core/process.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace driftlab {

pid_t start_process(const std::vector<std::string>& argv, const std::string& stdout_path,
                    const std::string& stderr_path) {
  if (argv.empty()) return -1;
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!stdout_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  if (!stderr_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  std::fflush(stdout);
  std::fflush(stderr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  return rc == 0 ? pid : -1;
}

int exit_code_of(int wait_status) {
  if (WIFSIGNALED(wait_status)) return 128 + WTERMSIG(wait_status);
  return WIFEXITED(wait_status) ? WEXITSTATUS(wait_status) : 127;
}

int wait_process(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return 127;
  }
  return exit_code_of(status);
}

int run_process(const std::vector<std::string>& argv, const std::string& stdout_path,
                const std::string& stderr_path) {
  const pid_t pid = start_process(argv, stdout_path, stderr_path);
  return pid < 0 ? 127 : wait_process(pid);
}

std::string last_line_of(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

Status run_plot_script(const char* script, const std::string& name, const std::string& dir,
                       const std::vector<std::string>& args) {
  const std::string path = (std::filesystem::path(dir) / ("." + name)).string();
  {
    FILE* f = std::fopen(path.c_str(), "w");
    const size_t n = std::strlen(script);
    bool ok = f != nullptr && std::fwrite(script, 1, n, f) == n;
    if (f != nullptr && std::fclose(f) != 0) ok = false;
    if (!ok) return Error{path + ": cannot write", ErrorCode::kCannotWrite};
  }
  // The first Python that has matplotlib: $DRIFTLAB_PYTHON, the one on PATH, then Debian's (where
  // python3-matplotlib installs, should PATH lead to another, like pyenv's).
  std::vector<std::string> pythons = {"python3", "/usr/bin/python3"};
  if (const char* p = std::getenv("DRIFTLAB_PYTHON"); p != nullptr && *p != 0) pythons.insert(pythons.begin(), p);
  // Python's standard error is kept in memory (a full disk has no room for it) and summed up in one line: a write
  // error was a 51-line traceback, and exit 2.
  const int err_fd = ::memfd_create("driftlab-plot-stderr", MFD_CLOEXEC);
  const std::string err_path =
      err_fd >= 0 ? "/proc/" + std::to_string(::getpid()) + "/fd/" + std::to_string(err_fd) : std::string();
  int code = 127;
  for (const auto& python : pythons) {
    std::vector<std::string> argv = {python, path};
    argv.insert(argv.end(), args.begin(), args.end());
    code = run_process(argv, "", err_path);
    if (code != 3 && code != 127) break;
  }
  std::remove(path.c_str());
  const std::string said = err_path.empty() ? std::string() : last_line_of(err_path);
  if (err_fd >= 0) ::close(err_fd);
  if (code == 3 || code == 127) {
    return Error{"no python3 with matplotlib (Debian: apt-get install python3-matplotlib, or run scripts/bootstrap)"};
  }
  // The script's exit 4: "DIR: cannot write the page: No space left on device".
  if (code == 4 && !said.empty()) return Error{said, ErrorCode::kCannotWrite};
  if (code != 0) {
    return Error{"drawing the plots failed (python3 exited with " + std::to_string(code) + ")" +
                 (said.empty() ? std::string() : ": " + said)};
  }
  return {};
}

}  // namespace driftlab
