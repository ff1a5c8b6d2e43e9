// formats/compression: a size a file declares (a bag chunk's header, a zstd frame's own) is a claim, allocated for
// up front only when the compressed bytes could expand that far; data that really does expand further still comes
// out whole. Found by the fuzzers (docs/bad-input.md): 65 bytes of MCAP made the reader allocate and zero-fill
// 1.7 GB; a 49-byte bag chunk asked for 4 GiB.
#include <gtest/gtest.h>
#include <lz4frame.h>

#include <cstdint>
#include <string>
#include <vector>

#include "formats/compression.h"

namespace driftlab::formats {
namespace {

constexpr size_t kMiB = size_t{1} << 20;

/// A zstd frame declaring `declared` bytes of content that holds one raw block of `content`.
std::vector<uint8_t> lying_zstd_frame(uint32_t declared, const std::string& content) {
  std::vector<uint8_t> f = {0x28, 0xb5, 0x2f, 0xfd,  // magic
                            0x80,                    // a 4-byte content size, a window descriptor, no checksum
                            0x00};                   // a 1 KiB window
  for (int i = 0; i < 4; ++i) f.push_back(static_cast<uint8_t>(declared >> (8 * i)));
  const uint32_t block = (static_cast<uint32_t>(content.size()) << 3) | 1;  // raw, the last block
  for (int i = 0; i < 3; ++i) f.push_back(static_cast<uint8_t>(block >> (8 * i)));
  f.insert(f.end(), content.begin(), content.end());
  return f;
}

TEST(Compression, PlausibleSizeIsAThousandfoldAndAMebibyte) {
  EXPECT_TRUE(plausible_size(0, kMiB));
  EXPECT_FALSE(plausible_size(0, kMiB + 1));
  EXPECT_TRUE(plausible_size(100, size_t{100} * 1024 + kMiB));
  EXPECT_FALSE(plausible_size(100, size_t{100} * 1024 + kMiB + 1));
  EXPECT_FALSE(plausible_size(49, 0xffffffffu));
}

// The fuzzer's frame: 64 MiB declared in 16 bytes. It fails to decode either way; before the fix the buffer had
// been sized (and zero-filled) to the declared size first.
TEST(Compression, AZstdFrameDeclaringMoreThanItsBytesCanHoldIsNotAllocatedFor) {
  const auto frame = lying_zstd_frame(64 * kMiB, "abc");
  for (const bool reused : {false, true}) {
    std::vector<uint8_t> out;
    std::string error;
    if (reused) {
      Decompressor d;
      error = d.run(Codec::kZstd, frame, 0, out);
    } else {
      error = decompress(Codec::kZstd, frame, 0, out);
    }
    EXPECT_FALSE(error.empty());
    EXPECT_LE(out.capacity(), 2 * kMiB) << "reused " << reused;
    EXPECT_LE(out.size(), 3u);
  }
}

// A bag chunk's header saying 4 GiB: the chunk still decompresses, into a buffer of what it holds.
TEST(Compression, AnExpectedSizeBeyondWhatTheBytesCanHoldIsNotReserved) {
  const std::vector<uint8_t> text(1000, 'x');
  for (const Codec codec : {Codec::kLz4Frame, Codec::kZstd}) {
    std::vector<uint8_t> packed;
    Compressor c(codec, 1);
    ASSERT_EQ(c.run(text, packed), "");
    std::vector<uint8_t> out;
    EXPECT_EQ(decompress(codec, packed, 0xffffffffu, out), "");
    EXPECT_EQ(out, text);
    EXPECT_LE(out.capacity(), 2 * kMiB);
  }
}

// Data that truly expands beyond the rule (16 MiB of zeros in under a kilobyte) is not a lie: it comes out whole.
TEST(Compression, DataThatReallyExpandsFurtherStillComesOutWhole) {
  const std::vector<uint8_t> zeros(16 * kMiB, 0);
  std::vector<uint8_t> packed;
  Compressor c(Codec::kZstd, 1);
  ASSERT_EQ(c.run(zeros, packed), "");
  ASSERT_FALSE(plausible_size(packed.size(), zeros.size())) << packed.size();
  std::vector<uint8_t> out;
  EXPECT_EQ(decompress(Codec::kZstd, packed, zeros.size(), out), "");
  EXPECT_EQ(out, zeros);
}

// An lz4 frame whose content checksum is wrong keeps what it decodes and says so, as a bad bz2 CRC does: the decoder
// returns nothing of a call that ends on a bad checksum, and a ROS 1 bag chunk of 500 intact messages lost them all.
TEST(Compression, AWrongLz4ChecksumKeepsTheDataAndSaysSo) {
  std::vector<uint8_t> text(200000);
  for (size_t i = 0; i < text.size(); ++i) text[i] = static_cast<uint8_t>(i * 7 % 251);
  LZ4F_preferences_t prefs{};
  prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
  std::vector<uint8_t> packed(LZ4F_compressFrameBound(text.size(), &prefs));
  packed.resize(LZ4F_compressFrame(packed.data(), packed.size(), text.data(), text.size(), &prefs));
  std::vector<uint8_t> out;
  ASSERT_EQ(decompress(Codec::kLz4Frame, packed, text.size(), out), "");
  ASSERT_EQ(out, text);
  packed.back() ^= 0x55;  // the content checksum is the frame's last 4 bytes
  EXPECT_EQ(decompress(Codec::kLz4Frame, packed, text.size(), out), "lz4: the content checksum does not match");
  EXPECT_EQ(out, text);
}

}  // namespace
}  // namespace driftlab::formats
