#include "formats/internal/decompress.h"

#include <bzlib.h>
#include <lz4frame.h>
#include <zlib.h>

#include <algorithm>
#include <climits>

namespace driftlab::formats::internal {
namespace {

constexpr size_t kStep = 1 << 20;

/// Grows out so that at least kStep bytes are free after `used`; returns the free room.
size_t room(std::vector<uint8_t>& out, size_t used) {
  if (out.size() < used + kStep) out.resize(used + kStep);
  return out.size() - used;
}

std::string bz2(std::span<const uint8_t> in, std::vector<uint8_t>& out) {
  bz_stream s{};
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) return "bz2: cannot start the decoder";
  s.next_in = const_cast<char*>(reinterpret_cast<const char*>(in.data()));
  size_t left = in.size();
  size_t used = 0;
  std::string error;
  for (;;) {
    const unsigned feed = static_cast<unsigned>(std::min<size_t>(left, UINT_MAX));
    s.avail_in = feed;
    const size_t free = std::min<size_t>(room(out, used), UINT_MAX);
    s.next_out = reinterpret_cast<char*>(out.data() + used);
    s.avail_out = static_cast<unsigned>(free);
    const int rc = BZ2_bzDecompress(&s);
    used += free - s.avail_out;
    left -= feed - s.avail_in;
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

std::string lz4(std::span<const uint8_t> in, std::vector<uint8_t>& out) {
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return "lz4: cannot start the decoder";
  size_t pos = 0;
  size_t used = 0;
  std::string error;
  for (;;) {
    size_t free = room(out, used);
    size_t src = in.size() - pos;
    const size_t hint = LZ4F_decompress(ctx, out.data() + used, &free, in.data() + pos, &src, nullptr);
    used += free;
    pos += src;
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

std::string gzip(std::span<const uint8_t> in, std::vector<uint8_t>& out) {
  z_stream s{};
  if (inflateInit2(&s, 15 + 32) != Z_OK) return "gzip: cannot start the decoder";  // +32: gzip or zlib header
  size_t pos = 0;
  size_t used = 0;
  std::string error;
  for (;;) {
    const size_t feed = std::min<size_t>(in.size() - pos, UINT_MAX);
    s.next_in = const_cast<Bytef*>(in.data() + pos);
    s.avail_in = static_cast<uInt>(feed);
    const size_t free = std::min<size_t>(room(out, used), UINT_MAX);
    s.next_out = out.data() + used;
    s.avail_out = static_cast<uInt>(free);
    const int rc = inflate(&s, Z_NO_FLUSH);
    used += free - s.avail_out;
    pos += feed - s.avail_in;
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

}  // namespace

std::string decompress(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out) {
  out.clear();
  out.reserve(expected_size);
  switch (codec) {
    case Codec::kNone:
      out.assign(in.begin(), in.end());
      return {};
    case Codec::kBz2: return bz2(in, out);
    case Codec::kLz4Frame: return lz4(in, out);
    case Codec::kGzip: return gzip(in, out);
  }
  return "unknown codec";
}

}  // namespace driftlab::formats::internal
