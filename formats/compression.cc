#include "formats/compression.h"

#include <bzlib.h>
#include <lz4frame.h>
#include <sys/stat.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <memory>

namespace driftlab::formats {
namespace {

constexpr size_t kStep = 1 << 20;

/// Grows out so that up to kStep bytes are free after `used`, never past `cap` (the limit and one byte more, to see
/// that a block goes past its limit); returns the free room (> 0 while used < cap).
size_t room(std::vector<uint8_t>& out, size_t used, size_t cap) {
  const size_t want = used + std::min(kStep, cap - used);
  if (out.size() < want) out.resize(want);
  return std::min(out.size(), cap) - used;
}

std::string over(size_t limit, bool declared) {
  return "decodes to more than the " + std::to_string(limit) + " bytes " +
         (declared ? std::string("it declares") : "a block without a declared size may") + " (stopped there)";
}

std::string bz2(std::span<const uint8_t> in, std::vector<uint8_t>& out, size_t limit, bool declared) {
  bz_stream s{};
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) return "bz2: cannot start the decoder";
  s.next_in = const_cast<char*>(reinterpret_cast<const char*>(in.data()));
  size_t left = in.size();
  size_t used = 0;
  std::string error;
  for (;;) {
    const unsigned feed = static_cast<unsigned>(std::min<size_t>(left, UINT_MAX));
    s.avail_in = feed;
    const size_t free = std::min<size_t>(room(out, used, limit + 1), UINT_MAX);
    s.next_out = reinterpret_cast<char*>(out.data() + used);
    s.avail_out = static_cast<unsigned>(free);
    const int rc = BZ2_bzDecompress(&s);
    used += free - s.avail_out;
    left -= feed - s.avail_in;
    if (used > limit) {
      error = "bz2: " + over(limit, declared);
      used = limit;
      break;
    }
    if (rc == BZ_STREAM_END) break;
    if (rc != BZ_OK) {
      error = rc == BZ_DATA_ERROR ? "bz2: data integrity error" : "bz2: not bz2 data";
      break;
    }
    if (left == 0 && s.avail_out != 0) {
      error = "bz2: the compressed block ends early";
      break;
    }
  }
  BZ2_bzDecompressEnd(&s);
  out.resize(used);
  return error;
}

std::string lz4(std::span<const uint8_t> in, std::vector<uint8_t>& out, size_t limit, bool declared,
                bool skip_checksums = false) {
  LZ4F_decompressOptions_t options{};
  options.skipChecksums = skip_checksums ? 1 : 0;
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return "lz4: cannot start the decoder";
  size_t pos = 0;
  size_t used = 0;
  std::string error;
  for (;;) {
    size_t free = room(out, used, limit + 1);
    size_t src = in.size() - pos;
    const size_t hint = LZ4F_decompress(ctx, out.data() + used, &free, in.data() + pos, &src, &options);
    used += free;
    pos += src;
    if (used > limit) {
      error = "lz4: " + over(limit, declared);
      used = limit;
      break;
    }
    if (LZ4F_isError(hint)) {
      error = std::string("lz4: ") + LZ4F_getErrorName(hint);
      break;
    }
    if (hint == 0) break;  // frame complete
    if (pos == in.size() && free == 0) {
      error = "lz4: the compressed block ends early";
      break;
    }
  }
  LZ4F_freeDecompressionContext(ctx);
  out.resize(used);
  return error;
}

/// lz4, and when the content checksum fails, decoded again without checking it: the decoder returns nothing of a call
/// that ends on a bad checksum, so a chunk whose content checksum was wrong lost every intact message (a bad bz2 CRC
/// keeps them). The data is kept and the failure reported, as for bz2; the records' own checks then apply.
std::string lz4_keeping_data(std::span<const uint8_t> in, std::vector<uint8_t>& out, size_t limit, bool declared) {
  std::string error = lz4(in, out, limit, declared);
  if (error.find("contentChecksum_invalid") == std::string::npos) return error;
  std::vector<uint8_t> again;
  if (!lz4(in, again, limit, declared, true).empty()) return error;
  out.swap(again);
  return "lz4: the content checksum does not match";
}

std::string gzip(std::span<const uint8_t> in, std::vector<uint8_t>& out, size_t limit, bool declared) {
  z_stream s{};
  if (inflateInit2(&s, 15 + 32) != Z_OK) return "gzip: cannot start the decoder";  // +32: gzip or zlib header
  size_t pos = 0;
  size_t used = 0;
  std::string error;
  for (;;) {
    const size_t feed = std::min<size_t>(in.size() - pos, UINT_MAX);
    s.next_in = const_cast<Bytef*>(in.data() + pos);
    s.avail_in = static_cast<uInt>(feed);
    const size_t free = std::min<size_t>(room(out, used, limit + 1), UINT_MAX);
    s.next_out = out.data() + used;
    s.avail_out = static_cast<uInt>(free);
    const int rc = inflate(&s, Z_NO_FLUSH);
    used += free - s.avail_out;
    pos += feed - s.avail_in;
    if (used > limit) {
      error = "gzip: " + over(limit, declared);
      used = limit;
      break;
    }
    if (rc == Z_STREAM_END) {
      // Concatenated gzip members (what `cat a.gz b.gz` makes) go on.
      if (pos < in.size() && inflateReset(&s) == Z_OK) continue;
      break;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      error = std::string("gzip: ") + (s.msg ? s.msg : "corrupt data");
      break;
    }
    if (pos == in.size() && s.avail_out != 0) {
      error = "gzip: the file ends early";
      break;
    }
  }
  inflateEnd(&s);
  out.resize(used);
  return error;
}

/// zstd: in one call when the frame says its size and is whole (the fast path), else streamed so that a frame cut
/// short or damaged still gives what was decoded before the damage.
std::string zstd(ZSTD_DCtx* ctx, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out,
                 size_t limit, bool declared_limit) {
  const unsigned long long declared = ZSTD_getFrameContentSize(in.data(), in.size());
  size_t whole = expected_size;
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared != ZSTD_CONTENTSIZE_ERROR) whole = declared;
  // The frame's header is the file's word too: 1.7 GB declared in a 20-byte frame was allocated and zero-filled
  // before the frame failed to decode (the ros2 fuzzer).
  if (whole > 0 && whole <= limit && plausible_size(in.size(), whole)) {
    out.resize(whole);
    const size_t n = ZSTD_decompressDCtx(ctx, out.data(), out.size(), in.data(), in.size());
    if (!ZSTD_isError(n)) {
      out.resize(n);
      return {};
    }
  }
  ZSTD_DCtx_reset(ctx, ZSTD_reset_session_only);
  ZSTD_inBuffer src{in.data(), in.size(), 0};
  size_t used = 0;
  std::string error;
  for (;;) {
    const size_t free = room(out, used, limit + 1);
    ZSTD_outBuffer dst{out.data() + used, free, 0};
    const size_t rc = ZSTD_decompressStream(ctx, &dst, &src);
    used += dst.pos;
    if (used > limit) {
      error = "zstd: " + over(limit, declared_limit);
      used = limit;
      break;
    }
    if (ZSTD_isError(rc)) {
      error = std::string("zstd: ") + ZSTD_getErrorName(rc);
      break;
    }
    if (rc == 0) {
      if (src.pos == src.size) break;  // frames may follow one another
      continue;
    }
    if (src.pos == src.size && dst.pos < free) {
      error = "zstd: the compressed block ends early";
      break;
    }
  }
  out.resize(used);
  return error;
}

}  // namespace

bool plausible_size(size_t compressed, uint64_t size) {
  return size <= uint64_t{compressed} * 1024 + (uint64_t{1} << 20);
}

std::string block_size_problem(size_t compressed, uint64_t declared) {
  if (declared > kMaxBlockBytes) {
    return "declares " + std::to_string(declared) + " bytes uncompressed, more than the " +
           std::to_string(kMaxBlockBytes) +
           " a block may hold: not decompressed (a decompression bomb or a damaged "
           "header)";
  }
  if (declared > kFreeBlockBytes && declared > uint64_t{compressed} * kMaxRatio) {
    return "declares " + std::to_string(declared) + " bytes uncompressed from " + std::to_string(compressed) +
           " compressed, more than " + std::to_string(kMaxRatio) +
           " times as many: not decompressed (a "
           "decompression bomb or a damaged header)";
  }
  return {};
}

DecodeBudget::DecodeBudget(uint64_t file_bytes)
    : total_(kFreeTotalBytes + std::min<uint64_t>(file_bytes, UINT64_MAX / 1024 / kTotalRatio) * kTotalRatio) {}

std::string DecodeBudget::take(uint64_t declared) {
  if (declared > total_ - used_) {
    return "its blocks would decompress to more than " + std::to_string(total_) + " bytes in all (" +
           std::to_string(kTotalRatio) + " times the file's size and " + std::to_string(kFreeTotalBytes) +
           "): the rest is not decompressed (a decompression bomb)";
  }
  used_ += declared;
  return {};
}

Decompressor::Decompressor() : zstd_(ZSTD_createDCtx()) {}
Decompressor::~Decompressor() { ZSTD_freeDCtx(static_cast<ZSTD_DCtx*>(zstd_)); }

std::string Decompressor::run(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out,
                              size_t limit) {
  if (codec != Codec::kZstd) return decompress(codec, in, expected_size, out, limit);
  // Not cleared first: zstd() sizes out to what it decodes, and a reused buffer is then not zero-filled again
  // before every block (a memory pass over every chunk of an MCAP file).
  const bool declared = expected_size > 0;
  return zstd(static_cast<ZSTD_DCtx*>(zstd_), in, expected_size, out, declared ? expected_size : limit, declared);
}

Compressor::Compressor(Codec codec, int level) : codec_(codec), level_(level) {
  if (codec_ == Codec::kZstd) zstd_ = ZSTD_createCCtx();
}
Compressor::~Compressor() { ZSTD_freeCCtx(static_cast<ZSTD_CCtx*>(zstd_)); }

std::string Compressor::run(std::span<const uint8_t> in, std::vector<uint8_t>& out) {
  if (codec_ == Codec::kZstd) {
    // Grown, not cleared first: a reused buffer is not zero-filled again before every block (only what it grows by).
    if (out.size() < ZSTD_compressBound(in.size())) out.resize(ZSTD_compressBound(in.size()));
    const size_t n =
        ZSTD_compressCCtx(static_cast<ZSTD_CCtx*>(zstd_), out.data(), out.size(), in.data(), in.size(), level_);
    if (ZSTD_isError(n)) return std::string("zstd: ") + ZSTD_getErrorName(n);
    out.resize(n);
    return {};
  }
  out.clear();
  if (codec_ == Codec::kLz4Frame) {
    LZ4F_preferences_t prefs{};
    prefs.frameInfo.contentSize = in.size();
    prefs.compressionLevel = level_;
    out.resize(LZ4F_compressFrameBound(in.size(), &prefs));
    const size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
    if (LZ4F_isError(n)) return std::string("lz4: ") + LZ4F_getErrorName(n);
    out.resize(n);
    return {};
  }
  out.assign(in.begin(), in.end());
  return {};
}

Status decompress_file(Codec codec, const std::string& in, const std::string& out, uint64_t max_out) {
  if (codec != Codec::kZstd) return Error(in + ": only zstd files are decompressed whole");
  std::unique_ptr<FILE, int (*)(FILE*)> src(std::fopen(in.c_str(), "rb"), &std::fclose);
  if (!src) return Error(in + ": cannot open: " + std::strerror(errno));
  const std::string partial = out + ".partial";
  std::unique_ptr<FILE, int (*)(FILE*)> dst(std::fopen(partial.c_str(), "wb"), &std::fclose);
  if (!dst) return Error(out + ": cannot create: " + std::strerror(errno), ErrorCode::kCannotWrite);
  std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> ctx(ZSTD_createDCtx(), &ZSTD_freeDCtx);
  std::vector<uint8_t> ibuf(ZSTD_DStreamInSize()), obuf(ZSTD_DStreamOutSize());
  std::string error;
  size_t last_rc = 0;
  uint64_t read_total = 0;
  // A bound on what is written out: a few KB of zstd frames of zeros would fill the disk.
  struct stat st {};
  const uint64_t in_bytes = ::fstat(fileno(src.get()), &st) == 0 ? static_cast<uint64_t>(st.st_size) : 0;
  const uint64_t bound = max_out != 0 ? max_out : DecodeBudget(in_bytes).total();
  uint64_t written = 0;
  bool bomb = false;
  bool cannot_write = false;  // the output's fault, not the input's
  for (;;) {
    const size_t got = std::fread(ibuf.data(), 1, ibuf.size(), src.get());
    if (got == 0) break;
    ZSTD_inBuffer input{ibuf.data(), got, 0};
    while (input.pos < input.size && error.empty()) {
      ZSTD_outBuffer output{obuf.data(), obuf.size(), 0};
      last_rc = ZSTD_decompressStream(ctx.get(), &output, &input);
      if (ZSTD_isError(last_rc)) {
        error = "at byte " + std::to_string(read_total + input.pos) + ": zstd: " + ZSTD_getErrorName(last_rc);
      }
      written += output.pos;
      if (written > bound) {
        error = "decompresses to more than " + std::to_string(bound) + " bytes, the bound for a file of " +
                std::to_string(in_bytes) + " (stopped at byte " + std::to_string(read_total + input.pos) +
                "; nothing written): a decompression bomb";
        bomb = true;
        break;
      }
      if (output.pos && std::fwrite(obuf.data(), 1, output.pos, dst.get()) != output.pos) {
        error = "cannot write " + partial + ": " + std::strerror(errno);
        cannot_write = true;
      }
    }
    read_total += got;
    if (!error.empty()) break;
  }
  if (error.empty() && last_rc != 0)
    error = "the compressed file ends early (at byte " + std::to_string(read_total) + ")";
  const bool closed = std::fclose(dst.release()) == 0;
  if (error.empty() && !closed) error = "cannot write " + partial;
  cannot_write = cannot_write || !closed;
  // What was decoded before damage is kept: the reader of the decompressed file reports the cut itself.
  if (!closed || bomb || std::rename(partial.c_str(), out.c_str()) != 0) {
    std::remove(partial.c_str());
    if (error.empty()) return Error(in + ": cannot rename into place", ErrorCode::kCannotWrite);
    return Error(in + ": " + error, cannot_write ? ErrorCode::kCannotWrite : ErrorCode::kBadInput);
  }
  if (!error.empty()) return Error(in + ": " + error);
  return {};
}

std::string decompress(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out,
                       size_t limit) {
  out.clear();
  // A block stops at the size it declares: a 9 KB bag's chunks declaring a few bytes each inflated to 3.4 GB.
  const bool declared = expected_size > 0;
  if (declared) limit = expected_size;
  // A bag chunk's header saying 4 GiB over 40 bytes asked for 4 GiB here.
  if (declared && plausible_size(in.size(), expected_size)) out.reserve(expected_size + 1);
  switch (codec) {
    case Codec::kNone: out.assign(in.begin(), in.end()); return {};
    case Codec::kBz2: return bz2(in, out, limit, declared);
    case Codec::kLz4Frame: return lz4_keeping_data(in, out, limit, declared);
    case Codec::kGzip: return gzip(in, out, limit, declared);
    case Codec::kZstd: {
      Decompressor d;
      return d.run(codec, in, expected_size, out, limit);
    }
  }
  return "unknown codec";
}

}  // namespace driftlab::formats
