// formats/mcap: the writer's files read back by the reader in every compression, and held to the specification's
// promises: CRCs checked, a cut or damaged file gives every intact message and names the damage by offset, an
// unknown compression or a private record is passed over. The schemas driftlab writes equal rosbag2's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>

#include "formats/export_mcap.h"
#include "formats/mcap.h"
#include "tests/test_util.h"

namespace driftlab::formats {
namespace {

struct Read {
  std::vector<McapMessage> messages;
  std::vector<std::vector<uint8_t>> data;
  std::vector<McapProblem> problems;
  std::vector<McapMetadata> metadata;
};

Read read_all(McapReader& r) {
  Read out;
  r.read(
      [&](const McapMessage& m) {
        out.messages.push_back(m);
        out.data.emplace_back(m.data.begin(), m.data.end());
      },
      [&](const McapProblem& p) { out.problems.push_back(p); },
      [&](const McapMetadata& m) { out.metadata.push_back(m); });
  return out;
}

std::vector<uint8_t> payload(int i) { return test::payload(static_cast<uint64_t>(i), 50 + static_cast<size_t>(i % 300)); }

/// 1,000 messages on 3 channels (2 schemas), chunks of about 8 KiB, and a metadata record.
void write_file(const std::string& path, McapCompression compression) {
  auto w = McapWriter::create(path, {.compression = compression, .level = compression == McapCompression::kLz4 ? 0 : 1,
                                     .chunk_bytes = 8 << 10});
  ASSERT_TRUE(w.ok()) << w.error().message;
  const uint16_t s1 = w->add_schema("pkg/msg/A", "ros2msg", "int32 a\n");
  const uint16_t s2 = w->add_schema("pkg/msg/B", "ros2msg", "string b\n");
  const uint16_t c[3] = {w->add_channel(s1, "/a", "cdr", {{"k", "v"}}), w->add_channel(s2, "/b", "cdr"),
                         w->add_channel(0, "/raw", "json")};
  for (int i = 0; i < 1000; ++i) {
    // Log times not in order, as a recorder can write them.
    ASSERT_TRUE(w->write(c[i % 3], static_cast<uint32_t>(i), 1'000'000'000ull + static_cast<uint64_t>((i * 7919) % 1000),
                         5, payload(i)).ok());
  }
  ASSERT_TRUE(w->add_metadata("driftlab.test", {{"key", "value"}}).ok());
  ASSERT_TRUE(w->close().ok());
}

class Compressions : public ::testing::TestWithParam<McapCompression> {};

TEST_P(Compressions, WrittenFilesReadBackWhole) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), GetParam());
  auto r = McapReader::open(dir.file("f.mcap"));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Read got = read_all(*r);
  EXPECT_TRUE(got.problems.empty()) << got.problems[0].what;
  EXPECT_EQ(r->profile(), "ros2");
  ASSERT_EQ(got.messages.size(), 1000u);
  for (int i = 0; i < 1000; ++i) {
    const auto& m = got.messages[static_cast<size_t>(i)];
    EXPECT_EQ(m.channel->topic, i % 3 == 0 ? "/a" : i % 3 == 1 ? "/b" : "/raw");
    EXPECT_EQ(m.sequence, static_cast<uint32_t>(i));
    EXPECT_EQ(m.log_time, 1'000'000'000ull + static_cast<uint64_t>((i * 7919) % 1000));
    EXPECT_EQ(m.publish_time, 5u);
    EXPECT_EQ(got.data[static_cast<size_t>(i)], payload(i));
    EXPECT_GE(m.offset_in_chunk, 0);  // every message in a chunk
  }
  EXPECT_EQ(got.messages[0].channel->schema->name, "pkg/msg/A");
  EXPECT_EQ(got.messages[0].channel->metadata.at(0).second, "v");
  EXPECT_EQ(got.messages[2].channel->schema, nullptr);
  ASSERT_EQ(got.metadata.size(), 1u);
  EXPECT_EQ(got.metadata[0].name, "driftlab.test");
  ASSERT_NE(r->statistics(), nullptr);  // the summary was found (and its CRC held)
  EXPECT_EQ(r->statistics()->message_count, 1000u);
  EXPECT_EQ(r->statistics()->channel_message_counts.at(2), 333u);
}

INSTANTIATE_TEST_SUITE_P(Mcap, Compressions,
                         ::testing::Values(McapCompression::kNone, McapCompression::kZstd, McapCompression::kLz4));

// A flipped byte inside an uncompressed chunk: its CRC says so (the data section's CRC too), and every other
// chunk still reads.
TEST(Mcap, CrcsCatchDamage) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), McapCompression::kNone);
  auto bytes = test::read_file(dir.file("f.mcap"));
  const auto victim = payload(500);  // a message's bytes, inside a chunk
  auto at = std::search(bytes.begin(), bytes.end(), victim.begin(), victim.end());
  ASSERT_NE(at, bytes.end());
  at[10] ^= 0x40;
  auto r = McapReader::from_memory(bytes);
  ASSERT_TRUE(r.ok());
  const Read got = read_all(*r);
  bool chunk_crc = false, data_crc = false;
  for (const auto& p : got.problems) {
    chunk_crc |= p.what.find("chunk: its records fail their CRC") != std::string::npos;
    data_crc |= p.what.find("the data section fails its CRC") != std::string::npos;
  }
  EXPECT_TRUE(chunk_crc);
  EXPECT_TRUE(data_crc);
  EXPECT_GE(got.messages.size(), 990u);
}

// A footer whose summary start points inside the magic or just past it, where no Data End record can end: the
// reader looked 13 bytes before it, which wrapped below the file's first byte (found by the ros2 fuzzer); now the
// summary is damage and every message of the data section is still read.
TEST(Mcap, SummaryStartInsideTheMagicIsDamage) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), McapCompression::kNone);
  const auto whole = test::read_file(dir.file("f.mcap"));
  auto r0 = McapReader::from_memory(whole);
  ASSERT_TRUE(r0.ok());
  const size_t all = read_all(*r0).messages.size();
  for (const uint64_t start : {uint64_t{1}, uint64_t{5}, uint64_t{12}, uint64_t{20}}) {
    auto bytes = whole;
    const size_t at = bytes.size() - 8 - 4 - 8 - 8;  // the footer's summary_start: before its two fields and magic
    for (int i = 0; i < 8; ++i) bytes[at + static_cast<size_t>(i)] = static_cast<uint8_t>(start >> (8 * i));
    auto r = McapReader::from_memory(bytes);
    ASSERT_TRUE(r.ok()) << start;
    EXPECT_EQ(read_all(*r).messages.size(), all) << start;
  }
}

// A file cut anywhere: the messages before the cut are read (those of the cut chunk that were decoded whole), the
// cut is reported with its offset, and nothing is invented.
TEST(Mcap, CutFilesKeepWhatIsWhole) {
  test::TempDir dir;
  for (auto c : {McapCompression::kNone, McapCompression::kZstd, McapCompression::kLz4}) {
    write_file(dir.file("f.mcap"), c);
    const auto whole = test::read_file(dir.file("f.mcap"));
    size_t last = 0;
    for (size_t cut : {whole.size() / 4, whole.size() / 2, whole.size() - 100}) {
      std::vector<uint8_t> bytes(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(cut));
      auto r = McapReader::from_memory(bytes);
      ASSERT_TRUE(r.ok());
      const Read got = read_all(*r);
      ASSERT_FALSE(got.problems.empty());
      EXPECT_NE(got.problems.back().what.find("the file ends inside"), std::string::npos) << got.problems.back().what;
      EXPECT_GT(got.messages.size(), last);
      last = got.messages.size();
      for (size_t i = 0; i < got.messages.size(); ++i) EXPECT_EQ(got.data[i], payload(static_cast<int>(i)));
    }
    EXPECT_GE(last, 900u);
  }
}

// Garbage between records: reported with the bytes skipped, and reading goes on at the next chunk.
TEST(Mcap, GarbageIsSkippedToTheNextRecord) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), McapCompression::kZstd);
  auto bytes = test::read_file(dir.file("f.mcap"));
  // The second chunk's opcode: 0x06 after the first chunk and its message indexes.
  auto r0 = McapReader::from_memory(bytes);
  ASSERT_TRUE(r0.ok());
  const Read clean = read_all(*r0);
  uint64_t second = 0;
  for (const auto& m : clean.messages)
    if (m.offset != clean.messages[0].offset) {
      second = m.offset;
      break;
    }
  ASSERT_GT(second, 0u);
  bytes.insert(bytes.begin() + static_cast<ptrdiff_t>(second), 300, 0xAB);
  auto r = McapReader::from_memory(bytes);
  ASSERT_TRUE(r.ok());
  const Read got = read_all(*r);
  ASSERT_FALSE(got.problems.empty());
  EXPECT_EQ(got.problems[0].offset, second);
  EXPECT_NE(got.problems[0].what.find("300 bytes skipped"), std::string::npos) << got.problems[0].what;
  EXPECT_EQ(got.messages.size(), 1000u);
}

/// The offsets of the chunks that hold messages, in file order.
std::vector<uint64_t> chunk_offsets(const Read& r) {
  std::vector<uint64_t> at;
  for (const auto& m : r.messages)
    if (at.empty() || at.back() != m.offset) at.push_back(m.offset);
  return at;
}

/// A read of a file in memory, pipelined (the default) or on the calling thread alone.
Read read_bytes(std::span<const uint8_t> bytes, bool pipelined = true) {
  auto r = McapReader::from_memory(bytes);
  EXPECT_TRUE(r.ok());
  if (!r) return {};
  r->set_pipelined(pipelined);
  return read_all(*r);
}

/// What a read gave, message by message and problem by problem, in one comparable text.
std::string trace(McapReader& r) {
  const Read got = read_all(r);
  std::string t;
  for (size_t i = 0; i < got.messages.size(); ++i) {
    const auto& m = got.messages[i];
    t += "message " + m.channel->topic + " " + std::to_string(m.sequence) + " " + std::to_string(m.log_time) + " " +
         std::to_string(m.offset) + " " + std::to_string(m.offset_in_chunk) + " " + std::to_string(got.data[i].size()) +
         " " + std::string(got.data[i].begin(), got.data[i].end()) + "\n";
  }
  for (const auto& p : got.problems) t += "problem " + std::to_string(p.offset) + " " + p.what + "\n";
  for (const auto& m : got.metadata) t += "metadata " + m.name + "\n";
  if (r.statistics()) t += "statistics " + std::to_string(r.statistics()->message_count) + "\n";
  return t;
}

// A zstd chunk in the middle that does not decompress (its frame's first bytes overwritten): reported once, at its
// offset, with the data section's CRC (the bytes changed); every message before and after it is read, in order.
// The same pipelined (the default: chunks decompressed on a second thread) and on the calling thread alone.
TEST(Mcap, CorruptChunkInTheMiddleIsReportedOnceAndTheRestRead) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), McapCompression::kZstd);
  auto bytes = test::read_file(dir.file("f.mcap"));
  const Read clean = read_bytes(bytes);
  const auto chunks = chunk_offsets(clean);
  ASSERT_GE(chunks.size(), 10u);  // enough for the reading thread to run ahead
  const uint64_t victim = chunks[chunks.size() / 2];
  // opcode, length, start and end times, uncompressed size, CRC, "zstd", records length: then the frame.
  const size_t frame = victim + 9 + 8 + 8 + 8 + 4 + 4 + 4 + 8;
  ASSERT_EQ(bytes[frame], 0x28);  // zstd's magic, little endian: 28 b5 2f fd
  std::fill_n(bytes.begin() + static_cast<ptrdiff_t>(frame), 4, 0);
  for (const bool pipelined : {true, false}) {
    const Read got = read_bytes(bytes, pipelined);
    ASSERT_EQ(got.problems.size(), 2u);
    EXPECT_EQ(got.problems[0].offset, victim);
    EXPECT_EQ(got.problems[0].what, "chunk: zstd: Unknown frame descriptor");
    EXPECT_NE(got.problems[1].what.find("the data section fails its CRC"), std::string::npos);
    std::vector<size_t> want;  // the clean read's messages outside the victim
    for (size_t i = 0; i < clean.messages.size(); ++i)
      if (clean.messages[i].offset != victim) want.push_back(i);
    ASSERT_EQ(got.messages.size(), want.size());
    EXPECT_LT(want.size(), clean.messages.size());
    for (size_t i = 0; i < want.size(); ++i) {
      EXPECT_EQ(got.messages[i].sequence, clean.messages[want[i]].sequence);
      EXPECT_EQ(got.messages[i].offset, clean.messages[want[i]].offset);
      EXPECT_EQ(got.data[i], clean.data[want[i]]);
    }
  }
}

// The pipelined read makes the same calls in the same order as the read on the calling thread alone, on whole
// files and on every kind of damage the reader recovers from: a chunk that does not decompress or fails its CRC,
// garbage between records (reading goes on at the next record, found with the channels known so far), a record
// length that runs past the end, a file cut inside a chunk.
TEST(Mcap, PipelinedReadMakesTheSameCalls) {
  test::TempDir dir;
  for (auto c : {McapCompression::kNone, McapCompression::kZstd, McapCompression::kLz4}) {
    write_file(dir.file("f.mcap"), c);
    const auto whole = test::read_file(dir.file("f.mcap"));
    const auto chunks = chunk_offsets(read_bytes(whole));
    ASSERT_GE(chunks.size(), 10u);
    std::vector<std::vector<uint8_t>> variants = {whole};
    auto damaged = whole;  // bytes flipped inside three chunks' records
    for (size_t k : {size_t{1}, chunks.size() / 2, chunks.size() - 2}) damaged[chunks[k] + 200] ^= 0x5a;
    variants.push_back(damaged);
    auto garbage = whole;  // garbage before the middle chunk
    garbage.insert(garbage.begin() + static_cast<ptrdiff_t>(chunks[chunks.size() / 2]), 77, 0xAB);
    variants.push_back(garbage);
    auto length = whole;  // the middle chunk's length runs past the end of the file
    std::fill_n(length.begin() + static_cast<ptrdiff_t>(chunks[chunks.size() / 2] + 1), 8, 0x7f);
    variants.push_back(length);
    variants.emplace_back(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(chunks[chunks.size() / 2] + 300));
    for (size_t v = 0; v < variants.size(); ++v) {
      auto serial = McapReader::from_memory(variants[v]);
      auto pipelined = McapReader::from_memory(variants[v]);
      ASSERT_TRUE(serial.ok() && pipelined.ok());
      serial->set_pipelined(false);
      const std::string want = trace(*serial);
      EXPECT_EQ(trace(*pipelined), want) << "compression " << static_cast<int>(c) << ", variant " << v;
      if (v > 0) {
        EXPECT_NE(want.find("problem "), std::string::npos) << "variant " << v << " is not damaged";
      }
    }
  }
}

// A callback that throws stops the read (the reading thread is stopped and joined), and the reader reads again.
TEST(Mcap, ThrowingCallbackStopsThePipelinedRead) {
  test::TempDir dir;
  write_file(dir.file("f.mcap"), McapCompression::kZstd);
  auto r = McapReader::open(dir.file("f.mcap"));
  ASSERT_TRUE(r.ok());
  int seen = 0;
  EXPECT_THROW(r->read(
                   [&](const McapMessage&) {
                     if (++seen == 10) throw std::runtime_error("enough");
                   },
                   [](const McapProblem&) {}),
               std::runtime_error);
  EXPECT_EQ(seen, 10);
  const Read again = read_all(*r);
  EXPECT_EQ(again.messages.size(), 1000u);
  EXPECT_TRUE(again.problems.empty());
}

// The writer compresses and writes closed chunks on a thread of its own: a write that fails there (a full disk)
// reaches the caller, naming the file, at a later write or at close; nothing after it is written.
TEST(Mcap, WriteErrorsOnTheWritingThreadReachTheCaller) {
  auto w = McapWriter::create("/dev/full", {.chunk_bytes = 4 << 10, .atomic = false});
  ASSERT_TRUE(w.ok()) << w.error().message;
  const uint16_t c = w->add_channel(0, "/raw", "json");
  Status st;
  for (int i = 0; i < 1000 && st; ++i) st = w->write(c, static_cast<uint32_t>(i), 1, 1, payload(i));
  if (st) st = w->close();
  ASSERT_FALSE(st);
  EXPECT_EQ(st.message().find("/dev/full: cannot write: No space left on device"), 0u) << st.message();
  EXPECT_FALSE(w->write(c, 0, 1, 1, payload(0)));
}

// Discarding a writer with chunks still queued for its writing thread leaves nothing behind.
TEST(Mcap, DiscardLeavesNothingBehind) {
  test::TempDir dir;
  auto w = McapWriter::create(dir.file("f.mcap"), {.chunk_bytes = 1 << 10});
  ASSERT_TRUE(w.ok());
  const uint16_t c = w->add_channel(0, "/raw", "json");
  for (int i = 0; i < 500; ++i) ASSERT_TRUE(w->write(c, static_cast<uint32_t>(i), 1, 1, payload(i)));
  w->discard();
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

/// Appends an MCAP record.
void record(std::vector<uint8_t>& b, uint8_t op, const std::vector<uint8_t>& content) {
  b.push_back(op);
  const uint64_t n = content.size();
  b.insert(b.end(), reinterpret_cast<const uint8_t*>(&n), reinterpret_cast<const uint8_t*>(&n) + 8);
  b.insert(b.end(), content.begin(), content.end());
}
void put_str(std::vector<uint8_t>& b, const std::string& s) {
  const auto n = static_cast<uint32_t>(s.size());
  b.insert(b.end(), reinterpret_cast<const uint8_t*>(&n), reinterpret_cast<const uint8_t*>(&n) + 4);
  b.insert(b.end(), s.begin(), s.end());
}
template <typename T>
void put(std::vector<uint8_t>& b, T v) {
  b.insert(b.end(), reinterpret_cast<const uint8_t*>(&v), reinterpret_cast<const uint8_t*>(&v) + sizeof(T));
}

// A file written record by record: messages outside chunks, a private record (0x80) and one of a later version
// (0x7f) passed over, a chunk with an unknown compression reported and skipped, no summary and no footer.
TEST(Mcap, UnindexedFileWithUnknownRecords) {
  std::vector<uint8_t> b = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
  std::vector<uint8_t> c;
  put_str(c, "");
  put_str(c, "hand");
  record(b, 0x01, c);
  c.clear();
  put<uint16_t>(c, 1);
  put<uint16_t>(c, 0);
  put_str(c, "/t");
  put_str(c, "json");
  put<uint32_t>(c, 0);
  record(b, 0x04, c);
  auto message = [&](uint32_t seq) {
    std::vector<uint8_t> m;
    put<uint16_t>(m, 1);
    put<uint32_t>(m, seq);
    put<uint64_t>(m, 100 + seq);
    put<uint64_t>(m, 100 + seq);
    m.push_back('{');
    m.push_back('}');
    record(b, 0x05, m);
  };
  message(0);
  record(b, 0x80, {1, 2, 3});
  record(b, 0x7f, {4, 5});
  const size_t chunk_at = b.size();
  c.clear();
  put<uint64_t>(c, 0);
  put<uint64_t>(c, 0);
  put<uint64_t>(c, 3);
  put<uint32_t>(c, 0);
  put_str(c, "brotli");
  put<uint64_t>(c, 3);
  c.insert(c.end(), {1, 2, 3});
  record(b, 0x06, c);
  message(1);
  auto r = McapReader::from_memory(b);
  ASSERT_TRUE(r.ok());
  const Read got = read_all(*r);
  ASSERT_EQ(got.messages.size(), 2u);
  EXPECT_EQ(got.messages[1].sequence, 1u);
  EXPECT_EQ(got.messages[1].offset_in_chunk, -1);
  ASSERT_EQ(got.problems.size(), 1u);
  EXPECT_EQ(got.problems[0].offset, chunk_at);
  EXPECT_NE(got.problems[0].what.find("\"brotli\""), std::string::npos);
  EXPECT_EQ(r->library(), "hand");
}

// The schemas driftlab writes for the types rosbag2 recorded in nav2_turtlebot.mcap are the same bytes.
TEST(Mcap, SchemasEqualRosbag2s) {
  const std::string bag = test::shared_data("bags/nav2_turtlebot.mcap");
  if (bag.empty()) return;
  auto r = McapReader::open(bag);
  ASSERT_TRUE(r.ok());
  std::map<std::string, std::string> theirs;
  r->read([&](const McapMessage& m) { theirs[m.channel->schema->name] = m.channel->schema->data; },
          [](const McapProblem& p) { ADD_FAILURE() << p.what; });
  ASSERT_EQ(theirs.size(), 3u);
  for (const auto& [name, data] : theirs) EXPECT_EQ(ros2_schema(name), data) << name;
}

}  // namespace
}  // namespace driftlab::formats
