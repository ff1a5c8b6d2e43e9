#include "apps/cli_util.h"

#include "core/install_layout.h"
#include "core/process.h"
#include "core/time.h"

#include <signal.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>

namespace driftlab::apps {

namespace {
thread_local OutputCapture* capture = nullptr;
}  // namespace

OutputCapture::OutputCapture() { capture = this; }
OutputCapture::~OutputCapture() { capture = nullptr; }

int fail(std::string_view message, int code) {
  if (capture != nullptr) {
    if (capture->error.empty()) capture->error = message;
    return code;
  }
  std::fprintf(stderr, "driftlab: %.*s\n", static_cast<int>(message.size()), message.data());
  return code;
}

namespace {
std::atomic<bool> g_stop{false};
void on_stop_signal(int) { g_stop.store(true); }
}  // namespace

const std::atomic<bool>* stop_on_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  return &g_stop;
}

std::string self_path() {
  const auto p = self_executable();
  return p.empty() ? "driftlab" : p.string();
}

int exit_code_for_input(const Error& error) {
  return error.code == ErrorCode::kCannotWrite ? kExitFailure : kExitBadInput;
}

Status write_atomically(const std::string& path, std::string_view bytes) {
  // Beside the target, renamed when whole: a failure leaves what PATH held and no partial file.
  const std::string partial = path + ".partial";
  FILE* f = std::fopen(partial.c_str(), "w");
  bool ok = f != nullptr && std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  if (f != nullptr && std::fclose(f) != 0) ok = false;
  const int err = errno;
  if (ok && std::rename(partial.c_str(), path.c_str()) != 0) ok = false;
  if (ok) return {};
  const int rename_err = errno;
  std::remove(partial.c_str());
  return Error{path + ": cannot write: " + std::strerror(err != 0 ? err : rename_err)};
}

bool write_output(const std::string& path, const std::string& text) {
  if (path == "-" && capture != nullptr) {
    capture->text += text;
    return true;
  }
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return true;
  }
  if (Status s = write_atomically(path, text); !s) {
    fail(s.message(), kExitFailure);
    return false;
  }
  return true;
}

int exit_code_for(const Error& error, std::string out) {
  while (out.size() > 1 && out.back() == '/') out.pop_back();
  const std::string& m = error.message;
  if (out.empty() || m.rfind(out, 0) != 0) return kExitBadInput;
  const char next = m.size() > out.size() ? m[out.size()] : '\0';
  return next == ':' || next == '/' || m.compare(out.size(), 8, ".partial") == 0 ? kExitFailure : kExitBadInput;
}

int run_program(const std::vector<std::string>& argv, const std::string& stdout_path, const std::string& stderr_path) {
  return run_process(argv, stdout_path, stderr_path);
}

Status run_plot_script(const char* script, const std::string& name, const std::string& dir,
                       const std::vector<std::string>& args) {
  const std::string path = (std::filesystem::path(dir) / ("." + name)).string();
  {
    FILE* f = std::fopen(path.c_str(), "w");
    const size_t n = std::strlen(script);
    bool ok = f != nullptr && std::fwrite(script, 1, n, f) == n;
    if (f != nullptr && std::fclose(f) != 0) ok = false;
    if (!ok) return Error{path + ": cannot write"};
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
    code = run_program(argv, "", err_path);
    if (code != 3 && code != 127) break;
  }
  std::remove(path.c_str());
  const std::string said = err_path.empty() ? std::string() : last_line_of(err_path);
  if (err_fd >= 0) ::close(err_fd);
  if (code == 3 || code == 127) {
    return Error{"no python3 with matplotlib (Debian: apt-get install python3-matplotlib, or run scripts/bootstrap)"};
  }
  if (code == 4 && !said.empty()) return Error{said};  // "DIR: cannot write the page: No space left on device"
  if (code != 0) {
    return Error{"drawing the plots failed (python3 exited with " + std::to_string(code) + ")" +
                 (said.empty() ? std::string() : ": " + said)};
  }
  return {};
}

bool split_log_channel(const std::string& src, std::string* log, std::string* channel) {
  const size_t colon = src.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == src.size()) return false;
  std::error_code ec;
  const std::string log_part = src.substr(0, colon);
  // Any file or folder (a bag) that exists: a FIFO or device is split too, so the command can refuse it by name.
  if (!std::filesystem::exists(log_part, ec)) return false;
  std::string whole = src;  // log or channel may alias src
  *log = whole.substr(0, colon);
  *channel = whole.substr(colon + 1);
  return true;
}

}  // namespace driftlab::apps
