// Decompression of whole blocks (bag and MCAP chunks, rosbag2's compressed files and messages) with Debian's libbz2,
// liblz4, libzstd and zlib, and compression of blocks for the MCAP writer. A block cut short or corrupt still
// gives every byte decoded before the damage, so the intact messages in it can be read.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::formats {

enum class Codec { kNone, kBz2, kLz4Frame, kGzip, kZstd };

/// Whether `compressed` bytes could plausibly decompress to `size`: at most 1024 times as many, and 1 MiB more. A
/// size a file declares beyond that (a bag's or MCAP chunk's header, a zstd frame's own) is a claim that is not
/// allocated for up front; the data is still decoded whole if it really expands that far, into a buffer grown as
/// its bytes come out.
bool plausible_size(size_t compressed, uint64_t size);

/// The most one block (a chunk, a message) may declare or decode to: 1 GiB.
constexpr uint64_t kMaxBlockBytes = uint64_t{1} << 30;
/// A block may declare up to 64 MiB whatever its compressed size (zero-filled images compress thousands of times);
/// beyond that, at most kMaxRatio times its compressed bytes.
constexpr uint64_t kFreeBlockBytes = uint64_t{64} << 20;
constexpr uint64_t kMaxRatio = 1024;
/// The most a block without a declared size (a rosbag2 message, a zstd frame without its size) decodes to.
constexpr size_t kUndeclaredLimit = size_t{256} << 20;

/// Why a block of `compressed` bytes declaring `declared` uncompressed is refused before it is decoded ("declares
/// 4294967295 bytes uncompressed, more than ..."), or "" when it may be decoded (up to its declared size).
std::string block_size_problem(size_t compressed, uint64_t declared);

/// What all the blocks of one file may decode to together: 1 GiB and kTotalRatio times the file's bytes. Every
/// block's declared size is taken from it before the block is decoded. Not thread-safe.
class DecodeBudget {
 public:
  static constexpr uint64_t kFreeTotalBytes = uint64_t{1} << 30;
  static constexpr uint64_t kTotalRatio = 256;
  explicit DecodeBudget(uint64_t file_bytes);
  /// "" when `declared` more bytes fit (and are taken), else why not (the budget is left as it was).
  std::string take(uint64_t declared);
  uint64_t total() const { return total_; }

 private:
  uint64_t total_;
  uint64_t used_ = 0;
};

/// Decompresses in into out (cleared first). expected_size is the size the block declares (0: none); decoding stops
/// there, and a block that would decode to more is an error ("bz2: decodes to more than the 100 bytes it
/// declares"), out holding the declared bytes. Without a declared size, decoding stops at `limit`. The buffer is
/// reserved up front only when plausible_size, else grown as bytes come out. Returns an empty string on
/// success, or what went wrong ("bz2: data integrity error"); out then holds what was decoded before it.
std::string decompress(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out,
                       size_t limit = kUndeclaredLimit);

/// Decompresses the file in (only kZstd: rosbag2's file compression) into out, streaming (memory stays bounded),
/// written beside out and renamed when whole. Errors name the file. What it writes is bounded by max_out (0: the
/// DecodeBudget of the file's size); past it, nothing is kept and the error says so.
Status decompress_file(Codec codec, const std::string& in, const std::string& out, uint64_t max_out = 0);

/// Reuses one decoder context between blocks (zstd's is worth keeping: it owns a window of the frame's size).
/// Not thread-safe; one per reader.
class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;
  /// As decompress(); out's old bytes are overwritten rather than cleared first (a reused buffer is not
  /// zero-filled again for every block).
  std::string run(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out,
                  size_t limit = kUndeclaredLimit);

 private:
  void* zstd_ = nullptr;  // ZSTD_DCtx
};

/// Compresses in with codec (kZstd at `level`, or kLz4Frame) into out (its old bytes overwritten). Keeps its
/// context between calls. Not thread-safe; one per writing thread.
class Compressor {
 public:
  Compressor(Codec codec, int level);
  ~Compressor();
  Compressor(const Compressor&) = delete;
  Compressor& operator=(const Compressor&) = delete;
  /// Empty on success, else what went wrong.
  std::string run(std::span<const uint8_t> in, std::vector<uint8_t>& out);

 private:
  Codec codec_;
  int level_;
  void* zstd_ = nullptr;  // ZSTD_CCtx
};

}  // namespace driftlab::formats
