#include "apps/cli_util.h"

#include "core/install_layout.h"
#include "core/text_file.h"

#include <signal.h>

#include <atomic>
#include <cstdio>

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

int exit_code_for(const Error& error) { return error.code == ErrorCode::kCannotWrite ? kExitFailure : kExitBadInput; }

bool write_output(const std::string& path, const std::string& text) {
  if (path == "-" && capture != nullptr) {
    capture->text += text;
    return true;
  }
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return true;
  }
  if (Status s = write_file_atomically(path, text); !s) {
    fail(s.message(), kExitFailure);
    return false;
  }
  return true;
}

}  // namespace driftlab::apps
