// Tests for LogReader: streaming, channel filters, seeking, and every kind of corruption.
#include "core/log_reader.h"

#include <gtest/gtest.h>

#include "core/log_format.h"
#include "core/log_writer.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using test::OwnedEvent;

/// A log of n events on channels A, B, C; event i at utime 1000 * i with a payload of 50 + 13 * (i % 7) bytes.
std::vector<uint8_t> make_log(int n, std::vector<OwnedEvent>* events = nullptr) {
  test::TempDir dir;
  auto w = LogWriter::create(dir.file("x.lcm"));
  for (int i = 0; i < n; ++i) {
    const std::string channel(1, static_cast<char>('A' + i % 3));
    const auto data = test::payload(i, 50 + 13 * (i % 7));
    EXPECT_TRUE(w->write(1000 * i, channel, data).ok());
    if (events != nullptr) events->push_back({i, 1000 * i, channel, data, 0});
  }
  EXPECT_TRUE(w->close().ok());
  auto bytes = test::read_file(dir.file("x.lcm"));
  if (events != nullptr) {
    auto read = test::read_all_memory(bytes);
    for (size_t i = 0; i < read.size(); ++i) (*events)[i].offset = read[i].offset;
  }
  return bytes;
}

std::vector<int64_t> numbers(const std::vector<OwnedEvent>& events) {
  std::vector<int64_t> out;
  for (const auto& e : events) out.push_back(e.event_number);
  return out;
}

std::vector<int64_t> range(int64_t from, int64_t to, int64_t skip = -1) {
  std::vector<int64_t> out;
  for (int64_t i = from; i < to; ++i)
    if (i != skip) out.push_back(i);
  return out;
}

TEST(LogReader, ReadsEveryEventOfACleanLogDespiteSyncWordsInPayloads) {
  // test::payload plants a sync word every 97 bytes: none of them may confuse the reader.
  std::vector<OwnedEvent> written;
  const auto bytes = make_log(300, &written);
  std::vector<Problem> problems;
  EXPECT_EQ(test::read_all_memory(bytes, &problems), written);
  EXPECT_TRUE(problems.empty());
}

TEST(LogReader, FiltersChannelsByFullRegexMatch) {
  const auto bytes = make_log(30);
  auto reader = LogReader::from_memory(bytes, {.channels = "A|C"});
  ASSERT_TRUE(reader.ok());
  Event e;
  int n = 0;
  while (reader->next(e)) {
    EXPECT_NE(e.channel, "B");
    ++n;
  }
  EXPECT_EQ(n, 20);
  // Full match: "A" does not match "AB" style partial patterns.
  auto partial = LogReader::from_memory(bytes, {.channels = "A."});
  ASSERT_TRUE(partial.ok());
  EXPECT_FALSE(partial->next(e));
}

TEST(LogReader, InvalidRegexIsAnError) {
  const auto bytes = make_log(3);
  auto reader = LogReader::from_memory(bytes, {.channels = "(unclosed"});
  ASSERT_FALSE(reader.ok());
  EXPECT_NE(reader.error().message.find("(unclosed"), std::string::npos);
}

TEST(LogReader, SeeksToTheFirstEventAtOrAfterATime) {
  const auto bytes = make_log(5000);  // several index blocks
  auto reader = LogReader::from_memory(bytes);
  ASSERT_TRUE(reader.ok());
  for (int64_t target : {0, 1, 999, 1000, 2500000, 4999000, 4999001, -5}) {
    ASSERT_TRUE(reader->seek(target).ok());
    Event e;
    if (target > 4999000) {
      EXPECT_FALSE(reader->next(e)) << target;
      continue;
    }
    ASSERT_TRUE(reader->next(e)) << target;
    EXPECT_EQ(e.utime, std::max<int64_t>(0, (target + 999) / 1000 * 1000)) << target;
  }
  reader->rewind();
  Event e;
  ASSERT_TRUE(reader->next(e));
  EXPECT_EQ(e.event_number, 0);
}

TEST(LogReader, ZeroLengthFileReportsEmptyAndEnds) {
  std::vector<Problem> problems;
  EXPECT_TRUE(test::read_all_memory({}, &problems).empty());
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kEmptyFile);
}

TEST(LogReader, TruncatedLastEventAtEveryCutKeepsAllEarlierEvents) {
  std::vector<OwnedEvent> written;
  const auto bytes = make_log(10, &written);
  const uint64_t last = written.back().offset;
  for (uint64_t cut = last + 1; cut < bytes.size(); ++cut) {
    std::vector<uint8_t> b(bytes.begin(), bytes.begin() + static_cast<long>(cut));
    std::vector<Problem> problems;
    const auto read = test::read_all_memory(b, &problems);
    ASSERT_EQ(numbers(read), range(0, 9)) << "cut at " << cut;
    ASSERT_EQ(problems.size(), 1u) << "cut at " << cut;
    EXPECT_EQ(problems[0].kind, ProblemKind::kTruncatedEvent);
    EXPECT_EQ(problems[0].offset, last);
  }
}

TEST(LogReader, GarbageBetweenEventsIsSkippedAndReported) {
  std::vector<OwnedEvent> written;
  auto bytes = make_log(20, &written);
  const std::vector<uint8_t> junk = {1, 2, 3, 0xED, 0xA1, 0xDA, 0x01, 9, 9, 9, 9, 9, 9, 9, 9};
  bytes.insert(bytes.begin() + static_cast<long>(written[5].offset), junk.begin(), junk.end());
  bytes.insert(bytes.begin(), junk.begin(), junk.end());  // garbage at the start, too
  bytes.insert(bytes.end(), junk.begin(), junk.end());    // and at the end
  std::vector<Problem> problems;
  const auto read = test::read_all_memory(bytes, &problems);
  EXPECT_EQ(numbers(read), range(0, 20));
  ASSERT_EQ(problems.size(), 3u);
  for (const auto& p : problems) EXPECT_EQ(p.kind, ProblemKind::kGarbage);
  EXPECT_EQ(problems[0].offset, 0u);
  EXPECT_EQ(problems[1].offset, written[5].offset + junk.size());
  EXPECT_EQ(problems[2].offset, bytes.size() - junk.size());
  for (size_t i = 0; i < read.size(); ++i) EXPECT_EQ(read[i].data, written[i].data);
}

TEST(LogReader, DataLengthPastTheEndMidFileLosesOnlyThatEvent) {
  std::vector<OwnedEvent> written;
  auto bytes = make_log(20, &written);
  logfmt::store_be32(bytes.data() + written[7].offset + 24, 0x7fffff00);
  std::vector<Problem> problems;
  const auto read = test::read_all_memory(bytes, &problems);
  EXPECT_EQ(numbers(read), range(0, 20, 7));
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kBadLength);
  EXPECT_EQ(problems[0].offset, written[7].offset);
}

TEST(LogReader, DataLengthOverrunningTheNextEventIsDetected) {
  std::vector<OwnedEvent> written;
  auto bytes = make_log(20, &written);
  // Longer than the event, but still inside the file: it would swallow event 8.
  const uint32_t len = logfmt::load_be32(bytes.data() + written[7].offset + 24);
  logfmt::store_be32(bytes.data() + written[7].offset + 24, len + 40);
  std::vector<Problem> problems;
  const auto read = test::read_all_memory(bytes, &problems);
  EXPECT_EQ(numbers(read), range(0, 20, 7));
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kBadLength);
}

TEST(LogReader, NegativeAndShortLengthsAreReported) {
  std::vector<OwnedEvent> written;
  auto bytes = make_log(20, &written);
  logfmt::store_be32(bytes.data() + written[3].offset + 24, 0xffffffff);  // -1
  const uint32_t len = logfmt::load_be32(bytes.data() + written[12].offset + 24);
  logfmt::store_be32(bytes.data() + written[12].offset + 24, len - 10);  // leaves 10 stray bytes
  std::vector<Problem> problems;
  const auto read = test::read_all_memory(bytes, &problems);
  // Event 12 is read short (its length says so) and the stray bytes after it are garbage.
  std::vector<int64_t> expected = range(0, 20, 3);
  EXPECT_EQ(numbers(read), expected);
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kBadLength);
  EXPECT_EQ(problems[1].kind, ProblemKind::kGarbage);
}

TEST(LogReader, AbsurdChannelLengthsAreReported) {
  std::vector<OwnedEvent> written;
  auto bytes = make_log(20, &written);
  logfmt::store_be32(bytes.data() + written[4].offset + 20, 0x40000000);
  logfmt::store_be32(bytes.data() + written[9].offset + 20, 0);
  std::vector<Problem> problems;
  const auto read = test::read_all_memory(bytes, &problems);
  std::vector<int64_t> expected;
  for (int64_t i = 0; i < 20; ++i)
    if (i != 4 && i != 9) expected.push_back(i);
  EXPECT_EQ(numbers(read), expected);
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_EQ(problems[0].kind, ProblemKind::kBadChannelLength);
  EXPECT_EQ(problems[0].offset, written[4].offset);
  EXPECT_EQ(problems[1].kind, ProblemKind::kBadChannelLength);
}

TEST(LogReader, OpenErrorsNameTheFile) {
  auto missing = LogReader::open("/nonexistent/log.lcm");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("/nonexistent/log.lcm"), std::string::npos);
  test::TempDir dir;
  auto directory = LogReader::open(dir.path());
  ASSERT_FALSE(directory.ok());
  EXPECT_NE(directory.error().message.find("directory"), std::string::npos);
}

}  // namespace
}  // namespace driftlab
