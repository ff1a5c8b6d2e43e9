// Tests for LogWriter: round trips, event numbering, large events, atomic mode and write failures; those that write
// run with the writer's own write(2) calls and with a background thread making them (WriteOptions::background).
#include "core/log_writer.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <filesystem>

#include "core/log_reader.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using test::OwnedEvent;

/// The parameter: WriteOptions::background.
class LogWriterModes : public ::testing::TestWithParam<bool> {};
INSTANTIATE_TEST_SUITE_P(LogWriter, LogWriterModes, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Background" : "Inline"; });

TEST_P(LogWriterModes, RoundTripsEventsInOrderWithConsecutiveEventNumbers) {
  test::TempDir dir;
  const std::string path = dir.file("a.lcm");
  std::vector<OwnedEvent> written;
  {
    auto w = LogWriter::create(path, {.buffer_bytes = 64 << 10, .background = GetParam()});
    ASSERT_TRUE(w.ok());
    // Sizes straddle the buffered and the direct (large) write paths, interleaved.
    const size_t sizes[] = {0, 1, 100, 40000, 5, 100000, 3, 1 << 20, 7};
    for (int i = 0; i < 90; ++i) {
      const std::string channel = "CH" + std::to_string(i % 4);
      auto data = test::payload(i, sizes[i % 9]);
      ASSERT_TRUE(w->write(1000 + i * 10, channel, data).ok());
      written.push_back({i, 1000 + i * 10, channel, data, 0});
    }
    EXPECT_EQ(w->events(), 90);
    ASSERT_TRUE(w->close().ok());
    EXPECT_EQ(w->bytes(), std::filesystem::file_size(path));
  }
  std::vector<Problem> problems;
  EXPECT_EQ(test::without_offsets(test::read_all(path, &problems)), written);
  EXPECT_TRUE(problems.empty());
}

TEST(LogWriter, RejectsEmptyAndOverlongChannelNames) {
  test::TempDir dir;
  auto w = LogWriter::create(dir.file("a.lcm"));
  ASSERT_TRUE(w.ok());
  EXPECT_FALSE(w->write(0, "", std::string_view("x")).ok());
  EXPECT_FALSE(w->write(0, std::string(256, 'c'), std::string_view("x")).ok());
  EXPECT_TRUE(w->write(0, std::string(255, 'c'), std::string_view("x")).ok());
}

TEST_P(LogWriterModes, AtomicModeShowsTheLogOnlyAfterClose) {
  test::TempDir dir;
  const std::string path = dir.file("a.lcm");
  auto w = LogWriter::create(path, {.atomic = true, .background = GetParam()});
  ASSERT_TRUE(w.ok());
  ASSERT_TRUE(w->write(1, "A", std::string_view("hello")).ok());
  ASSERT_TRUE(w->flush().ok());
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::exists(path + ".partial"));
  EXPECT_EQ(std::filesystem::file_size(path + ".partial"), w->bytes());  // flush() has handed it to the kernel
  ASSERT_TRUE(w->close().ok());
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  EXPECT_EQ(test::read_all(path).size(), 1u);
}

TEST_P(LogWriterModes, DiscardLeavesNothingBehind) {
  test::TempDir dir;
  const std::string path = dir.file("a.lcm");
  auto w = LogWriter::create(path, {.atomic = true, .background = GetParam()});
  ASSERT_TRUE(w.ok());
  ASSERT_TRUE(w->write(1, "A", std::string_view("hello")).ok());
  w->discard();
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(LogWriter, CreateErrorNamesTheFile) {
  auto w = LogWriter::create("/nonexistent-dir/x.lcm");
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.error().message.find("/nonexistent-dir/x.lcm"), std::string::npos);
}

TEST_P(LogWriterModes, FullDeviceGivesAnErrorNamingTheFile) {
  auto w = LogWriter::create("/dev/full", {.background = GetParam()});
  ASSERT_TRUE(w.ok());
  const auto data = test::payload(1, 2 << 20);
  Status st = w->write(0, "BIG", data);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("/dev/full"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("No space left on device"), std::string::npos) << st.message();
  // The failure is sticky.
  EXPECT_FALSE(w->write(0, "X", std::string_view("y")).ok());
}

/// A file-size limit makes write() fail part-way, like a disk that fills up; lifted on destruction.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    signal(SIGXFSZ, SIG_IGN);
    getrlimit(RLIMIT_FSIZE, &old_);
    rlimit limit = old_;
    limit.rlim_cur = bytes;
    EXPECT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &old_);
    signal(SIGXFSZ, SIG_DFL);
  }

 private:
  rlimit old_{};
};

TEST_P(LogWriterModes, AFailedWriteKeepsEveryCompleteEventReadable) {
  test::TempDir dir;
  const std::string path = dir.file("a.lcm");
  int64_t accepted = 0;
  Status failure;
  {
    FileSizeLimit full(200000);
    auto w = LogWriter::create(path, {.buffer_bytes = 16 << 10, .background = GetParam()});
    ASSERT_TRUE(w.ok());
    for (int i = 0; i < 1000 && failure.ok(); ++i) {
      failure = w->write(i, "CH", test::payload(i, 700));
      if (failure.ok()) ++accepted;
    }
    // In background mode the failure may come after the last event was accepted: close() returns it.
    if (failure.ok()) failure = w->close();
  }
  ASSERT_FALSE(failure.ok());
  EXPECT_NE(failure.message().find(path), std::string::npos);
  std::vector<Problem> problems;
  const auto events = test::read_all(path, &problems);
  EXPECT_TRUE(problems.empty()) << problems.front().detail;
  EXPECT_GT(events.size(), 200u);
  EXPECT_LE(static_cast<int64_t>(events.size()), accepted);
  for (size_t i = 0; i < events.size(); ++i) EXPECT_EQ(events[i].data, test::payload(i, 700));
}

TEST_P(LogWriterModes, AnAtomicLogCutShortNeverReplacesItsTarget) {
  // sim and replay write atomically; a full disk used to move the cut-short log over the user's file.
  test::TempDir dir;
  const std::string path = dir.file("a.lcm");
  test::write_file(path, {1, 2, 3});
  Status failure, closed;
  {
    FileSizeLimit full(100000);
    auto w = LogWriter::create(path, {.buffer_bytes = 16 << 10, .atomic = true, .background = GetParam()});
    ASSERT_TRUE(w.ok());
    for (int i = 0; i < 1000 && failure.ok(); ++i) failure = w->write(i, "CH", test::payload(i, 700));
    closed = w->close();
  }
  ASSERT_FALSE(failure.ok());
  EXPECT_FALSE(closed.ok());
  EXPECT_EQ(test::read_file(path), (std::vector<uint8_t>{1, 2, 3}));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

}  // namespace
}  // namespace driftlab
