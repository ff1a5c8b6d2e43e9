#include "apps/cli_util.h"

#include <fcntl.h>
#include <lcm/lcm.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <thread>

namespace driftlab::apps {

int fail(std::string_view message, int code) {
  std::fprintf(stderr, "driftlab: %.*s\n", static_cast<int>(message.size()), message.data());
  return code;
}

bool write_output(const std::string& path, const std::string& text) {
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return true;
  }
  FILE* f = std::fopen(path.c_str(), "w");
  bool ok = f != nullptr && std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (f != nullptr && std::fclose(f) != 0) ok = false;
  if (!ok) fail(path + ": cannot write: " + std::strerror(errno), kExitFailure);
  return ok;
}

int run_program(const std::vector<std::string>& argv, const std::string& stdout_path, const std::string& stderr_path) {
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
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return 127;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return 127;
  }
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 127;
}

std::string human_bytes(double bytes) {
  static const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int unit = 0;
  while (bytes >= 1024 && unit < 4) {
    bytes /= 1024;
    ++unit;
  }
  char buf[32];
  std::snprintf(buf, sizeof(buf), unit == 0 ? "%.0f %s" : "%.1f %s", bytes, kUnits[unit]);
  return buf;
}

std::string thousands(int64_t n) {
  std::string digits = std::to_string(n < 0 ? -n : n);
  std::string out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return n < 0 ? "-" + out : out;
}

std::string format_utime(int64_t utime) {
  constexpr int64_t kYear2000 = 946684800LL * 1000000;
  char buf[64];
  if (utime < kYear2000) {
    std::snprintf(buf, sizeof(buf), "%.6f s", static_cast<double>(utime) * 1e-6);
    return buf;
  }
  const time_t secs = static_cast<time_t>(utime / 1000000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%d %H:%M:%S", &tm);
  std::snprintf(buf, sizeof(buf), "%s.%06lld UTC", date, static_cast<long long>(utime % 1000000));
  return buf;
}

Progress::Progress(std::string label, Unit unit)
    : label_(std::move(label)),
      unit_(unit),
      enabled_(isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() {
  if (drawn_) std::fprintf(stderr, "\r\033[K");
}

void Progress::update(uint64_t done, uint64_t total) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  // Stay silent for quick jobs; then redraw at most every 100 ms.
  if (now - start_ < std::chrono::seconds(1) || now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  drawn_ = true;
  const double pct = total > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total) : 0.0;
  if (unit_ == Unit::kBytes) {
    std::fprintf(stderr, "\r\033[K%s %5.1f%%  %s of %s", label_.c_str(), pct, human_bytes(done).c_str(),
                 human_bytes(total).c_str());
  } else {
    std::fprintf(stderr, "\r\033[K%s %5.1f%%  %.0f s of %.0f s", label_.c_str(), pct,
                 static_cast<double>(done) * 1e-3, static_cast<double>(total) * 1e-3);
  }
  std::fflush(stderr);
}

Result<std::unique_ptr<LivePublisher>> LivePublisher::open(const std::string& url, double rate,
                                                          const std::string& option) {
  lcm_t* lcm = lcm_create(url.c_str());
  if (lcm == nullptr) return Error{option + " " + url + ": cannot open the LCM URL"};
  return std::unique_ptr<LivePublisher>(new LivePublisher(lcm, rate));
}

LivePublisher::~LivePublisher() { lcm_destroy(lcm_); }

void LivePublisher::publish(std::string_view channel, int64_t utime, std::span<const uint8_t> bytes) {
  if (first_ < 0) {
    first_ = utime;
    start_ = std::chrono::steady_clock::now();
  }
  if (rate_ > 0) {
    const auto due = start_ + std::chrono::microseconds(static_cast<int64_t>(static_cast<double>(utime - first_) / rate_));
    std::this_thread::sleep_until(due);
  }
  channel_.assign(channel);
  lcm_publish(lcm_, channel_.c_str(), bytes.data(), static_cast<unsigned int>(bytes.size()));
}

}  // namespace driftlab::apps
