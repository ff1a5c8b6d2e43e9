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

/// Decompresses in into out (cleared first; expected_size is a hint, 0 when unknown, reserved only when
/// plausible_size). Returns an empty string on
/// success, or what went wrong ("bz2: data integrity error"); out then holds what was decoded before it.
std::string decompress(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out);

/// Decompresses the file in (only kZstd: rosbag2's file compression) into out, streaming (memory stays bounded),
/// written beside out and renamed when whole. Errors name the file.
Status decompress_file(Codec codec, const std::string& in, const std::string& out);

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
  std::string run(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out);

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
