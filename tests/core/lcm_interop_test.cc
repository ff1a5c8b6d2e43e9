// Interoperability with the real LCM tools over udpm, run by tests/netns_run.sh inside a private network
// namespace: a log written by stock lcm-logger reads back exactly, and a log written by driftlab plays with
// lcm-logplayer and re-records identical payloads.
#include <gtest/gtest.h>
#include <lcm/lcm.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <thread>

#include "core/log_reader.h"
#include "core/log_writer.h"
#include "tests/lcm_netns_fixture.h"

extern char** environ;

namespace driftlab {
namespace {

const char* kUrl = test::kLcmUrl;
const char* kSyncChannel = "DRIFTLAB_TEST_SYNC";

using Message = test::LcmMessage;

/// The gap after sending a message. Stock lcm-logger loses messages in bursts (its reading thread falls behind the
/// socket's buffer), more so when the machine is loaded (CI runs these tests beside the sanitizer build's): these
/// tests are about the format, so the pace leaves it room, about 3 s for the 120 messages.
std::chrono::microseconds pace(const Message& m) {
  return std::chrono::microseconds(m.data.size() > 60000 ? 60000 : 10000);
}

pid_t spawn(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  EXPECT_EQ(posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ), 0) << args[0];
  return pid;
}

int stop(pid_t pid) {
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

/// Messages in a log, the handshake channel left out.
std::vector<Message> messages_in(const std::string& path) {
  std::vector<Message> out;
  auto reader = LogReader::open(path, {.channels = std::string("(?!") + kSyncChannel + ").*"});
  if (!reader.ok()) return out;
  Event e;
  while (reader->next(e)) out.push_back({std::string(e.channel), {e.data.begin(), e.data.end()}});
  return out;
}

bool log_has(const std::string& path, const std::string& channel) {
  auto reader = LogReader::open(path, {.channels = channel});
  Event e;
  return reader.ok() && reader->next(e);
}

/// Starts lcm-logger and waits until it demonstrably records (it logs our handshake messages).
pid_t start_logger(lcm_t* lcm, const std::string& path) {
  pid_t pid = spawn({"lcm-logger", "-f", "-q", "--flush-interval=10", std::string("--lcm-url=") + kUrl, path});
  const uint8_t ping[1] = {1};
  for (int i = 0; i < 250; ++i) {
    lcm_publish(lcm, kSyncChannel, ping, sizeof(ping));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (log_has(path, kSyncChannel)) return pid;
  }
  ADD_FAILURE() << "lcm-logger did not start recording within 5 s";
  return pid;
}

/// Waits until the log holds n messages besides the handshake, or 20 s pass.
void wait_for(const std::string& path, size_t n) {
  for (int i = 0; i < 400 && messages_in(path).size() < n; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

std::vector<Message> test_messages() {
  std::vector<Message> out;
  // Small messages and fragmented ones (LCM splits messages above ~64 KB into fragments).
  const size_t sizes[] = {0, 1, 64, 1000, 4000, 65000, 70000, 200000};
  for (int i = 0; i < 120; ++i) {
    out.push_back({"CHANNEL_" + std::to_string(i % 4), test::payload(i, sizes[i % 8])});
  }
  return out;
}

using LcmInterop = test::LcmNetnsTest;

TEST_F(LcmInterop, LogWrittenByLcmLoggerReadsBackExactly) {
  const std::string path = dir_.file("lcm-logger.lcm");
  const pid_t logger = start_logger(lcm_, path);
  const auto sent = test_messages();
  for (const auto& m : sent) {
    ASSERT_EQ(lcm_publish(lcm_, m.channel.c_str(), m.data.data(), static_cast<unsigned>(m.data.size())), 0);
    std::this_thread::sleep_for(pace(m));
  }
  wait_for(path, sent.size());
  stop(logger);

  std::vector<Problem> problems;
  const auto events = test::read_all(path, &problems);
  EXPECT_TRUE(problems.empty());
  EXPECT_EQ(messages_in(path), sent);
  // Event numbers from 0 without gaps; receive timestamps do not step back.
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].event_number, static_cast<int64_t>(i));
    if (i > 0) {
      EXPECT_GE(events[i].utime, events[i - 1].utime);
    }
  }
}

TEST_F(LcmInterop, LogWrittenByDriftlabPlaysWithLcmLogplayer) {
  const std::string ours = dir_.file("ours.lcm");
  const auto sent = test_messages();
  {
    auto w = LogWriter::create(ours);
    ASSERT_TRUE(w.ok());
    int64_t t = 1700000000000000;
    for (const auto& m : sent) {
      ASSERT_TRUE(w->write(t, m.channel, m.data).ok());
      t += pace(m).count();  // lcm-logplayer keeps these gaps
    }
    ASSERT_TRUE(w->close().ok());
  }
  const std::string recorded = dir_.file("recorded.lcm");
  const pid_t logger = start_logger(lcm_, recorded);
  const pid_t player = spawn({"lcm-logplayer", "-l", kUrl, ours});
  int status = 0;
  waitpid(player, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "lcm-logplayer failed";
  wait_for(recorded, sent.size());
  stop(logger);
  EXPECT_EQ(messages_in(recorded), sent);
}

}  // namespace
}  // namespace driftlab
