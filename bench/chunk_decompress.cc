// The decompressor's own speed on a bag (scripts/bench import): every chunk of an MCAP file or a ROS 1 bag
// decompressed, with the same libraries and contexts the readers use, and nothing else done. With --compress, the
// compressor's own speed: every chunk of an uncompressed MCAP file compressed with zstd at level 1, as
// `driftlab export mcap` compresses its chunks.
//   chunk_decompress [--compress] FILE   prints "BYTES_IN BYTES_OUT CHUNKS"
#include <cstdio>
#include <cstring>
#include <string_view>

#include "core/mapped_file.h"
#include "formats/compression.h"

using driftlab::formats::Codec;

int main(int argc, char** argv) {
  const bool compress = argc == 3 && std::string_view(argv[1]) == "--compress";
  if (argc != 2 && !compress) return 2;
  auto file = driftlab::MappedFile::open(argv[argc - 1]);
  if (!file) return 1;
  const auto b = file->bytes();
  driftlab::formats::Decompressor d;
  driftlab::formats::Compressor z(Codec::kZstd, 1);
  std::vector<uint8_t> out;
  uint64_t in_bytes = 0, out_bytes = 0, chunks = 0;
  auto run = [&](std::string_view compression, std::span<const uint8_t> data, size_t size) {
    const Codec c = compression == "zstd" ? Codec::kZstd
                    : compression == "lz4" ? Codec::kLz4Frame
                    : compression == "bz2" ? Codec::kBz2
                                           : Codec::kNone;
    if (compress) {
      z.run(data, out);
    } else {
      d.run(c, data, size, out);
    }
    in_bytes += data.size();
    out_bytes += out.size();
    ++chunks;
  };
  auto le32 = [&](size_t p) { uint32_t v; std::memcpy(&v, b.data() + p, 4); return v; };
  auto le64 = [&](size_t p) { uint64_t v; std::memcpy(&v, b.data() + p, 8); return v; };
  if (b.size() > 8 && b[0] == 0x89 && b[1] == 'M') {  // MCAP: opcode, uint64 length, content
    for (size_t p = 8; p + 9 <= b.size();) {
      const uint64_t len = le64(p + 1);
      if (b[p] == 0x06) {
        size_t q = p + 9 + 24;
        const uint32_t n = le32(q + 4);
        const std::string_view comp(reinterpret_cast<const char*>(b.data() + q + 8), n);
        q += 8 + n;
        const uint64_t records = le64(q);
        run(comp, b.subspan(q + 8, records), le64(p + 9 + 16));
      }
      p += 9 + len;
    }
  } else {  // ROS 1 bag: uint32 header length, fields, uint32 data length, data
    for (size_t p = 13; p + 8 <= b.size();) {
      const uint32_t hl = le32(p);
      std::string_view op, comp;
      uint32_t size = 0;
      for (size_t f = p + 4; f < p + 4 + hl;) {
        const uint32_t fl = le32(f);
        const std::string_view kv(reinterpret_cast<const char*>(b.data() + f + 4), fl);
        if (kv.starts_with("op=")) op = kv.substr(3);
        if (kv.starts_with("compression=")) comp = kv.substr(12);
        if (kv.starts_with("size=") && kv.size() == 9) std::memcpy(&size, kv.data() + 5, 4);
        f += 4 + fl;
      }
      const uint32_t dl = le32(p + 4 + hl);
      if (op == "\x05") run(comp, b.subspan(p + 8 + hl, dl), size);
      p += 8 + hl + dl;
    }
  }
  std::printf("%llu %llu %llu\n", static_cast<unsigned long long>(in_bytes), static_cast<unsigned long long>(out_bytes),
              static_cast<unsigned long long>(chunks));
  return 0;
}
