// Tests for LogIndex: the one-pass summary, the cache beside the log, staleness, and seek offsets.
#include "core/log_index.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/log_writer.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

void write_log(const std::string& path, int n, int64_t payload_bytes = 100) {
  auto w = LogWriter::create(path);
  ASSERT_TRUE(w.ok());
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(w->write(1000000 + 10000 * i, i % 4 == 0 ? "IMU" : "SCAN", test::payload(i, payload_bytes)).ok());
  }
  ASSERT_TRUE(w->close().ok());
}

TEST(LogIndex, SummarisesChannelsInOnePass) {
  test::TempDir dir;
  write_log(dir.file("a.lcm"), 100);
  auto index = LogIndex::load_or_build(dir.file("a.lcm"));
  ASSERT_TRUE(index.ok());
  const LogSummary& s = index->summary();
  EXPECT_EQ(s.events, 100);
  EXPECT_EQ(s.start_utime, 1000000);
  EXPECT_EQ(s.end_utime, 1000000 + 990000);
  ASSERT_EQ(s.channels.size(), 2u);
  EXPECT_EQ(s.channels[0].name, "IMU");
  EXPECT_EQ(s.channels[0].count, 25);
  EXPECT_EQ(s.channels[0].bytes, 2500);
  EXPECT_EQ(s.channels[0].first_utime, 1000000);
  EXPECT_EQ(s.channels[0].last_utime, 1000000 + 960000);
  EXPECT_EQ(s.channels[1].name, "SCAN");
  EXPECT_EQ(s.channels[1].count, 75);
  EXPECT_TRUE(s.problems.empty());
  // Small logs are not cached by default.
  EXPECT_FALSE(std::filesystem::exists(LogIndex::cache_path(dir.file("a.lcm"))));
}

TEST(LogIndex, CachesBesideTheLogAndRebuildsWhenStale) {
  test::TempDir dir;
  const std::string log = dir.file("a.lcm");
  write_log(log, 3000, 1000);
  auto first = LogIndex::load_or_build(log, {}, 0);
  ASSERT_TRUE(first.ok());
  EXPECT_FALSE(first->from_cache());
  ASSERT_TRUE(std::filesystem::exists(LogIndex::cache_path(log)));
  EXPECT_GE(first->entries().size(), 3u);

  auto second = LogIndex::load_or_build(log, {}, 0);
  ASSERT_TRUE(second.ok());
  EXPECT_TRUE(second->from_cache());
  EXPECT_EQ(second->summary().events, 3000);
  EXPECT_EQ(second->summary().channels.size(), 2u);
  EXPECT_EQ(second->entries().size(), first->entries().size());

  // The log changes: the cache is stale and the index is rebuilt.
  write_log(log, 10, 1000);
  auto third = LogIndex::load_or_build(log, {}, 0);
  ASSERT_TRUE(third.ok());
  EXPECT_FALSE(third->from_cache());
  EXPECT_EQ(third->summary().events, 10);
}

TEST(LogIndex, CountsStampsOnlyWithAHeaderReaderAndScansACacheWithoutThemOnce) {
  test::TempDir dir;
  const std::string log = dir.file("a.lcm");
  write_log(log, 100);
  // A reader that sees every message stamped 7 with its log time as seq: all but each channel's first repeat the
  // stamp before them with another seq.
  const HeaderReader headers = [](std::span<const uint8_t>, int64_t utime) {
    return std::optional(HeaderFields{utime, 7});
  };
  auto seek = LogIndex::load_or_build(log, {}, 0);  // as LogReader builds it, to seek: no counts
  ASSERT_TRUE(seek.ok());
  EXPECT_FALSE(seek->summary().stamps_counted);
  EXPECT_EQ(seek->summary().channels[0].stamped, 0);
  auto counted = LogIndex::load_or_build(log, {}, 0, headers);  // as info asks: the cache lacks them, so a scan
  ASSERT_TRUE(counted.ok());
  EXPECT_FALSE(counted->from_cache());
  EXPECT_TRUE(counted->summary().stamps_counted);
  EXPECT_EQ(counted->summary().channels[0].stamped, 25);
  EXPECT_EQ(counted->summary().channels[0].stamps_repeated, 24);
  EXPECT_EQ(counted->summary().channels[1].stamped, 75);
  EXPECT_EQ(counted->summary().channels[1].stamps_repeated, 74);
  // Cached with the counts now: either caller takes the cache.
  auto again = LogIndex::load_or_build(log, {}, 0, headers);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->from_cache());
  EXPECT_EQ(again->summary().channels[1].stamps_repeated, 74);
  auto seek_again = LogIndex::load_or_build(log, {}, 0);
  ASSERT_TRUE(seek_again.ok());
  EXPECT_TRUE(seek_again->from_cache());
}

TEST(LogIndex, CorruptCacheIsIgnored) {
  test::TempDir dir;
  const std::string log = dir.file("a.lcm");
  write_log(log, 500, 1000);
  ASSERT_TRUE(LogIndex::load_or_build(log, {}, 0).ok());
  auto cache = test::read_file(LogIndex::cache_path(log));
  for (size_t cut : {size_t{0}, size_t{5}, cache.size() / 2, cache.size() - 1}) {
    auto damaged = cache;
    damaged.resize(cut);
    test::write_file(LogIndex::cache_path(log), damaged);
    auto index = LogIndex::load_or_build(log, {}, 0);
    ASSERT_TRUE(index.ok());
    EXPECT_FALSE(index->from_cache());
    EXPECT_EQ(index->summary().events, 500);
  }
  cache[cache.size() / 2] ^= 0xff;  // flipped bits: caught by the checksum
  test::write_file(LogIndex::cache_path(log), cache);
  auto index = LogIndex::load_or_build(log, {}, 0);
  ASSERT_TRUE(index.ok());
  EXPECT_FALSE(index->from_cache());
}

TEST(LogIndex, SeekOffsetHandlesTimestampsThatStepBack) {
  test::TempDir dir;
  const std::string log = dir.file("a.lcm");
  {
    auto w = LogWriter::create(log);
    // 2 MiB events, one per index block; timestamps 10, 20, 15, 40, 30, 50.
    for (int64_t t : {10, 20, 15, 40, 30, 50}) ASSERT_TRUE(w->write(t, "C", test::payload(t, 2 << 20)).ok());
    ASSERT_TRUE(w->close().ok());
  }
  auto index = LogIndex::load_or_build(log);
  ASSERT_TRUE(index.ok());
  ASSERT_EQ(index->entries().size(), 6u);
  const auto& e = index->entries();
  EXPECT_EQ(index->seek_offset(5), e[0].offset);
  EXPECT_EQ(index->seek_offset(16), e[1].offset);  // the first event >= 16 is the one at 20
  EXPECT_EQ(index->seek_offset(35), e[3].offset);  // 40 comes before the 30 that steps back
  EXPECT_EQ(index->seek_offset(45), e[5].offset);
}

TEST(LogIndex, MissingFileIsAnErrorNamingIt) {
  auto index = LogIndex::load_or_build("/nonexistent/x.lcm");
  ASSERT_FALSE(index.ok());
  EXPECT_NE(index.error().message.find("/nonexistent/x.lcm"), std::string::npos);
}

}  // namespace
}  // namespace driftlab
