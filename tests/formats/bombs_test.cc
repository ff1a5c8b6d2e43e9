// Decompression bombs (issue 31): every decoder stops at the size its block declares, a block declaring more than
// its bytes can honestly hold is refused before it is decoded, a file's blocks together decode to a bounded
// amount, a CARMEN .clf.gz is inflated a line at a time, and a zstd file written out for rosbag2 is bounded. The
// bombs are built here: zero-filled data compressed (64 MiB of zeros are 79 bytes of bz2), with lying sizes.
#include <bzlib.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <zlib.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "formats/compression.h"
#include "formats/mcap.h"
#include "tests/test_util.h"

namespace driftlab::formats {
namespace {

using test::CmdResult;

constexpr size_t kMiB = size_t{1} << 20;
const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

std::vector<uint8_t> bz2_of_zeros(size_t n) {
  const std::vector<char> zeros(n, 0);
  std::vector<char> out(1024 + n / 100);
  auto len = static_cast<unsigned>(out.size());
  EXPECT_EQ(
      BZ2_bzBuffToBuffCompress(out.data(), &len, const_cast<char*>(zeros.data()), static_cast<unsigned>(n), 9, 0, 0),
      BZ_OK);
  return {out.begin(), out.begin() + len};
}

/// gzip (level 1) of `head`, then n zeros, then `tail`; streamed, so that the zeros are never held whole.
std::vector<uint8_t> gzip_of(const std::string& head, size_t n, const std::string& tail = "") {
  z_stream s{};
  EXPECT_EQ(deflateInit2(&s, 1, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY), Z_OK);
  std::vector<uint8_t> out;
  std::vector<uint8_t> buf(kMiB);
  auto feed = [&](const uint8_t* p, size_t len, int flush) {
    s.next_in = const_cast<Bytef*>(p);
    s.avail_in = static_cast<uInt>(len);
    do {
      s.next_out = buf.data();
      s.avail_out = static_cast<uInt>(buf.size());
      deflate(&s, flush);
      out.insert(out.end(), buf.data(), buf.data() + (buf.size() - s.avail_out));
    } while (s.avail_out == 0);
  };
  feed(reinterpret_cast<const uint8_t*>(head.data()), head.size(), Z_NO_FLUSH);
  const std::vector<uint8_t> zeros(kMiB, 0);
  for (size_t done = 0; done < n; done += kMiB) feed(zeros.data(), std::min(kMiB, n - done), Z_NO_FLUSH);
  feed(reinterpret_cast<const uint8_t*>(tail.data()), tail.size(), Z_FINISH);
  deflateEnd(&s);
  return out;
}

std::vector<uint8_t> packed_zeros(Codec codec, size_t n) {
  if (codec == Codec::kBz2) return bz2_of_zeros(n);
  if (codec == Codec::kGzip) return gzip_of("", n);
  std::vector<uint8_t> packed;
  Compressor c(codec, 1);
  EXPECT_EQ(c.run(std::vector<uint8_t>(n, 0), packed), "");
  return packed;
}

/// The peak resident size of this process's children so far, in MiB (each test runs in a process of its own).
long children_peak_mib() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return u.ru_maxrss / 1024;
}

// Each codec: a block of 64 MiB of zeros declaring 100 bytes gives 100 bytes and says so; one without a declared
// size stops at the limit given. Before, each came out whole (a 9 KB bag inflated to 3.4 GB).
TEST(DecompressionBomb, EveryDecoderStopsAtTheDeclaredSize) {
  for (const Codec codec : {Codec::kBz2, Codec::kGzip, Codec::kLz4Frame, Codec::kZstd}) {
    SCOPED_TRACE(static_cast<int>(codec));
    const auto packed = packed_zeros(codec, 64 * kMiB);
    std::vector<uint8_t> out;
    const std::string error = decompress(codec, packed, 100, out);
    EXPECT_NE(error.find("decodes to more than the 100 bytes it declares"), std::string::npos) << error;
    EXPECT_EQ(out.size(), 100u);
    EXPECT_LE(out.capacity(), 2 * kMiB);
    Decompressor d;
    out.clear();
    const std::string undeclared = d.run(codec, packed, 0, out, 3 * kMiB);
    EXPECT_NE(undeclared.find("more than the 3145728 bytes a block without a declared size may"), std::string::npos)
        << undeclared;
    EXPECT_EQ(out.size(), 3 * kMiB);
    EXPECT_LE(out.capacity(), 8 * kMiB);
    // The honest size still decodes whole.
    EXPECT_EQ(decompress(codec, packed, 64 * kMiB, out), "");
    EXPECT_EQ(out.size(), 64 * kMiB);
  }
}

TEST(DecompressionBomb, ABlockDeclaringMoreThanItCanHoldIsRefusedUpFront) {
  EXPECT_EQ(block_size_problem(79, 64 * kMiB), "");  // zero-filled images: up to 64 MiB whatever the ratio
  EXPECT_EQ(block_size_problem(1 * kMiB, 1000 * kMiB), "");
  EXPECT_NE(block_size_problem(79, 64 * kMiB + 1).find("more than 1024 times as many"), std::string::npos);
  EXPECT_NE(block_size_problem(100 * kMiB, 0xfffffff0u)
                .find("declares 4294967280 bytes uncompressed, more than the "
                      "1073741824 a block may hold"),
            std::string::npos);
  DecodeBudget budget(1000);
  EXPECT_EQ(budget.total(), (uint64_t{1} << 30) + 256000);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(budget.take(64 * kMiB), "") << i;
  EXPECT_NE(budget.take(256001).find("more than 1073997824 bytes in all"), std::string::npos) << budget.take(256001);
  EXPECT_EQ(budget.take(256000), "");
}

// --- A ROS 1 bag of bz2 chunks of zeros ---------------------------------------------------------------------

std::string field(const std::string& name, const std::string& value) {
  const auto n = static_cast<uint32_t>(name.size() + 1 + value.size());
  return std::string(reinterpret_cast<const char*>(&n), 4) + name + "=" + value;
}
std::string u32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string record(const std::string& header, const std::string& data) {
  return u32(static_cast<uint32_t>(header.size())) + header + u32(static_cast<uint32_t>(data.size())) + data;
}
std::string chunk(const std::vector<uint8_t>& packed, uint32_t declared) {
  return record(field("op", "\x05") + field("compression", "bz2") + field("size", u32(declared)),
                std::string(packed.begin(), packed.end()));
}

// 24 chunks of 79 bytes each inflating to 64 MiB but declaring 100 bytes, and one declaring 4 GiB: a 2 KB bag that
// decoded 1.5 GB (ten chunks at once on the prefetch threads). Each chunk is one line naming the file and its
// offset, exit 2, and the import stays small and quick.
TEST(DecompressionBomb, ABagOfLyingChunksIsStoppedAtTheirDeclaredSizes) {
  test::TempDir dir;
  const auto packed = bz2_of_zeros(64 * kMiB);
  std::string bag = "#ROSBAG V2.0\n" + record(field("op", "\x03") + field("index_pos", std::string(8, '\0')) +
                                                  field("conn_count", u32(0)) + field("chunk_count", u32(0)),
                                              std::string(64, ' '));
  const size_t huge_at = bag.size();
  bag += chunk(packed, 0xfffffff0u);
  std::vector<size_t> offsets;
  for (int i = 0; i < 24; ++i) {
    offsets.push_back(bag.size());
    bag += chunk(packed, 100);
  }
  const std::string in = dir.file("in.bag");
  test::write_file(in, {bag.begin(), bag.end()});
  ASSERT_LT(bag.size(), 10'000u);

  const auto t0 = std::chrono::steady_clock::now();
  const CmdResult r = test::run_capture(kDriftlab + " import '" + in + "' -o '" + dir.file("out.lcm") + "'");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.code, 2) << r.err;
  // The first few chunks are named (the import lists a few problems and counts the rest).
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_NE(r.err.find(in + ": at byte " + std::to_string(offsets[i]) +
                         ": chunk: bz2: decodes to more than the 100 bytes it declares (stopped there)\n"),
              std::string::npos)
        << r.err;
  }
  EXPECT_NE(r.err.find(in + ": at byte " + std::to_string(huge_at) +
                       ": chunk: declares 4294967280 bytes uncompressed, more than the 1073741824"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos);
  EXPECT_LT(children_peak_mib(), 300) << "MiB";
  EXPECT_LT(seconds, 20);
}

// An MCAP chunk declaring 100 bytes whose zstd frame holds 64 MiB: the decoder stops at 100 (it decoded all of
// it first, then compared).
TEST(DecompressionBomb, AnMcapChunkStopsAtItsDeclaredSize) {
  const auto packed = packed_zeros(Codec::kZstd, 64 * kMiB);
  std::vector<uint8_t> b = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
  auto put = [&](std::vector<uint8_t>& v, auto x) {
    v.insert(v.end(), reinterpret_cast<const uint8_t*>(&x), reinterpret_cast<const uint8_t*>(&x) + sizeof(x));
  };
  std::vector<uint8_t> c;
  put(c, uint64_t{0});
  put(c, uint64_t{0});
  put(c, uint64_t{100});  // uncompressed size
  put(c, uint32_t{0});    // no CRC
  put(c, uint32_t{4});
  c.insert(c.end(), {'z', 's', 't', 'd'});
  put(c, uint64_t{packed.size()});
  c.insert(c.end(), packed.begin(), packed.end());
  for (const uint64_t declared : {uint64_t{100}, uint64_t{1} << 40}) {
    std::memcpy(c.data() + 16, &declared, 8);
    std::vector<uint8_t> file = b;
    file.push_back(0x06);
    put(file, uint64_t{c.size()});
    file.insert(file.end(), c.begin(), c.end());
    for (const bool pipelined : {true, false}) {
      auto r = McapReader::from_memory(file);
      ASSERT_TRUE(r.ok());
      r->set_pipelined(pipelined);
      std::vector<McapProblem> problems;
      r->read([](const McapMessage&) {}, [&](const McapProblem& p) { problems.push_back(p); }, nullptr);
      ASSERT_GE(problems.size(), 1u);
      EXPECT_EQ(problems[0].offset, 8u);
      EXPECT_EQ(problems[0].what, declared == 100
                                      ? "chunk: zstd: decodes to more than the 100 bytes it declares (stopped there)"
                                      : "chunk: declares 1099511627776 bytes uncompressed, more than "
                                        "the 1073741824 a block may hold: not decompressed (a "
                                        "decompression bomb or a damaged header)");
    }
  }
}

// A .clf.gz of a few CARMEN lines and then 300 MiB of zeros without a line end: it was inflated whole into memory
// (and copied); it is read a line at a time, the endless line refused with one line naming the file and the line.
TEST(DecompressionBomb, ACarmenGzipIsReadALineAtATime) {
  test::TempDir dir;
  std::string head;
  for (int i = 0; i < 30; ++i) {  // the sniffers look at 20 lines
    head += "ODOM 1.0 2.0 0.5 0.1 0.0 0.0 " + std::to_string(100 + i) + ".0 host " + std::to_string(100 + i) + ".0\n";
  }
  const auto gz = gzip_of(head, 300 * kMiB, "\nODOM 1 2 0 0 0 0 200.0 host 200.0\n");
  ASSERT_LT(gz.size(), 2'000'000u);
  const std::string in = dir.file("bomb.clf.gz");
  test::write_file(in, gz);
  const CmdResult r = test::run_capture(kDriftlab + " import '" + in + "' -o '" + dir.file("out.lcm") + "'");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(in + ":31: a line longer than 16777216 bytes"), std::string::npos) << r.err;
  // Inflated whole it peaked at 912 MiB; a line at a time holds at most one 16 MiB line and the decoder's buffers:
  // 156 MiB peak under ASan (its shadow memory and quarantine), less in release. 300 tells the two apart.
  EXPECT_LT(children_peak_mib(), 300) << "MiB";
  // The lines before it are converted.
  EXPECT_GE(test::read_all(dir.file("out.lcm")).size(), 30u);
}

// rosbag2's file compression: what is written out is bounded (a few KB of frames of zeros filled the disk).
TEST(DecompressionBomb, AZstdFileWrittenOutIsBounded) {
  test::TempDir dir;
  const auto packed = packed_zeros(Codec::kZstd, 8 * kMiB);
  test::write_file(dir.file("f.db3.zstd"), packed);
  const Status s = decompress_file(Codec::kZstd, dir.file("f.db3.zstd"), dir.file("f.db3"), kMiB);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("decompresses to more than 1048576 bytes, the bound for a file of"), std::string::npos)
      << s.message();
  EXPECT_FALSE(std::filesystem::exists(dir.file("f.db3")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("f.db3.partial")));
  EXPECT_TRUE(decompress_file(Codec::kZstd, dir.file("f.db3.zstd"), dir.file("f.db3")).ok());
  EXPECT_EQ(std::filesystem::file_size(dir.file("f.db3")), 8 * kMiB);
}

}  // namespace
}  // namespace driftlab::formats
