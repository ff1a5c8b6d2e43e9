// Structure-aware mutations for the container and definition fuzzers (issue 31). Byte-level mutation almost never
// produces a compressed chunk that still decodes, or a definition whose types nest, so the cases that broke the
// readers (chunks whose declared size lies about what they decode to, types nested or repeated far beyond the
// seeds) stayed out of the fuzzers' reach. These parse the input's structure, change it the way an attacker would,
// and write it back:
//  - ROS 1 bag and MCAP chunks: decoded, then re-encoded with their declared uncompressed size made a lie (smaller,
//    larger, zero, the field's maximum), with zeros appended to the records (a bomb behind an honest or a lying
//    size), with the CRC cleared, or with the codec swapped;
//  - ROS message definitions: a chain of types each holding the next (nested past the readers' depth limit), a
//    type referring to itself or to one defined later, the same type defined twice, arrays of nested types.
// Every choice comes from the seed libFuzzer passes (derived from -seed), so a run is reproducible.
#pragma once

#include <bzlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "formats/compression.h"

namespace driftlab::fuzz {

using Rng = std::minstd_rand;

inline uint64_t pick(Rng& rng, uint64_t n) {
  return n == 0 ? 0 : std::uniform_int_distribution<uint64_t>(0, n - 1)(rng);
}

inline uint32_t get32(const uint8_t* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24;
}
inline uint64_t get64(const uint8_t* p) { return uint64_t{get32(p)} | uint64_t{get32(p + 4)} << 32; }
inline void put32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
inline void put64(std::vector<uint8_t>& out, uint64_t v) {
  put32(out, static_cast<uint32_t>(v));
  put32(out, static_cast<uint32_t>(v >> 32));
}

/// Compresses `in` with codec; false when it cannot (gzip is not written by either container).
inline bool compress(formats::Codec codec, const std::vector<uint8_t>& in, std::vector<uint8_t>& out) {
  using formats::Codec;
  if (codec == Codec::kNone) {
    out = in;
    return true;
  }
  if (codec == Codec::kBz2) {
    out.resize(in.size() + in.size() / 100 + 600);
    auto len = static_cast<unsigned>(out.size());
    if (BZ2_bzBuffToBuffCompress(reinterpret_cast<char*>(out.data()), &len,
                                 const_cast<char*>(reinterpret_cast<const char*>(in.data())),
                                 static_cast<unsigned>(in.size()), 1, 0, 0) != BZ_OK) {
      return false;
    }
    out.resize(len);
    return true;
  }
  if (codec != Codec::kZstd && codec != Codec::kLz4Frame) return false;
  formats::Compressor c(codec, 1);
  return c.run(in, out).empty();
}

/// The declared size a mutation gives a chunk whose records are `honest` bytes.
inline uint64_t lying_size(Rng& rng, uint64_t honest, uint64_t field_max) {
  switch (pick(rng, 7)) {
    case 0: return 0;
    case 1: return honest / 2;
    case 2: return honest > 0 ? honest - 1 : 1;
    case 3: return honest + 1 + pick(rng, 4096);
    case 4: return field_max;
    case 5: return formats::kMaxBlockBytes + pick(rng, 2);
    default: return honest;  // honest, with the records themselves changed
  }
}

/// Decodes a chunk, changes what it holds and what it declares, and encodes it again (maybe with another codec).
/// records: the decoded records (changed in place); returns false when the chunk cannot be decoded at all.
inline bool mutate_chunk(Rng& rng, formats::Codec& codec, std::span<const uint8_t> packed, uint64_t declared,
                         uint64_t field_max, const std::vector<formats::Codec>& codecs, size_t room,
                         std::vector<uint8_t>& out_packed, uint64_t& out_declared) {
  std::vector<uint8_t> records;
  if (codec == formats::Codec::kNone) {
    records.assign(packed.begin(), packed.end());
  } else {
    // Decoded as the reader would (stopping at the declared size); what came out before damage is kept.
    (void)formats::decompress(codec, packed, static_cast<size_t>(std::min<uint64_t>(declared, 1 << 20)), records,
                              1 << 20);
  }
  const uint64_t honest_before = records.size();
  if (pick(rng, 4) == 0) {
    // A bomb: zeros after the records. bz2 and zstd pack megabytes of zeros into tens of bytes, lz4 into 1/255.
    // Bounded so that a run stays quick (the readers decode what a chunk declares, up to its bytes' plausible
    // ratio): 256 KiB for bz2 and lz4, 2 MiB for zstd; far past any size the chunk declares all the same.
    const size_t most = codec == formats::Codec::kZstd ? size_t{2} << 20 : size_t{256} << 10;
    records.resize(records.size() + static_cast<size_t>(pick(rng, std::max<size_t>(most, 1)) + 1), 0);
  }
  if (pick(rng, 4) == 0 && !codecs.empty()) codec = codecs[pick(rng, codecs.size())];
  if (!compress(codec, records, out_packed)) return false;
  out_declared = pick(rng, 3) == 0 ? honest_before : lying_size(rng, records.size(), field_max);
  return out_packed.size() <= room;
}

// --- ROS 1 bags ------------------------------------------------------------------------------------------------

struct BagRecord {
  std::vector<std::pair<std::string, std::string>> fields;
  std::vector<uint8_t> data;
  const std::string* field(const std::string& name) const {
    for (const auto& [k, v] : fields) {
      if (k == name) return &v;
    }
    return nullptr;
  }
  std::string* field(const std::string& name) {
    for (auto& [k, v] : fields) {
      if (k == name) return &v;
    }
    return nullptr;
  }
};

/// A bag's records after its magic; stops at the first that does not parse (kept whole in `tail`).
inline std::vector<BagRecord> parse_bag(std::span<const uint8_t> b, std::vector<uint8_t>& tail) {
  std::vector<BagRecord> out;
  size_t p = 0;
  while (p + 4 <= b.size()) {
    const uint32_t hlen = get32(&b[p]);
    if (hlen > b.size() - p - 4 || b.size() - p - 4 - hlen < 4) break;
    BagRecord r;
    size_t q = p + 4;
    const size_t hend = q + hlen;
    bool ok = true;
    while (q < hend) {
      if (hend - q < 4) {
        ok = false;
        break;
      }
      const uint32_t flen = get32(&b[q]);
      q += 4;
      if (flen > hend - q) {
        ok = false;
        break;
      }
      const std::string f(reinterpret_cast<const char*>(&b[q]), flen);
      q += flen;
      const size_t eq = f.find('=');
      if (eq == std::string::npos) {
        ok = false;
        break;
      }
      r.fields.emplace_back(f.substr(0, eq), f.substr(eq + 1));
    }
    if (!ok) break;
    // A record cut short by the end of the input (a seed is a file's first bytes) keeps what there is.
    const uint32_t dlen = std::min<uint64_t>(get32(&b[hend]), b.size() - hend - 4);
    r.data.assign(b.begin() + static_cast<ptrdiff_t>(hend + 4), b.begin() + static_cast<ptrdiff_t>(hend + 4 + dlen));
    out.push_back(std::move(r));
    p = hend + 4 + dlen;
  }
  tail.assign(b.begin() + static_cast<ptrdiff_t>(p), b.end());
  return out;
}

inline void write_bag(const std::vector<BagRecord>& records, const std::vector<uint8_t>& tail,
                      std::vector<uint8_t>& out) {
  for (const auto& r : records) {
    std::vector<uint8_t> header;
    for (const auto& [k, v] : r.fields) {
      put32(header, static_cast<uint32_t>(k.size() + 1 + v.size()));
      header.insert(header.end(), k.begin(), k.end());
      header.push_back('=');
      header.insert(header.end(), v.begin(), v.end());
    }
    put32(out, static_cast<uint32_t>(header.size()));
    out.insert(out.end(), header.begin(), header.end());
    put32(out, static_cast<uint32_t>(r.data.size()));
    out.insert(out.end(), r.data.begin(), r.data.end());
  }
  out.insert(out.end(), tail.begin(), tail.end());
}

/// Mutates one chunk of a bag (the bytes after its magic) into `out`; false when there is none to mutate.
inline bool mutate_bag(Rng& rng, std::span<const uint8_t> bag, size_t max_size, std::vector<uint8_t>& out) {
  std::vector<uint8_t> tail;
  auto records = parse_bag(bag, tail);
  std::vector<size_t> chunks;
  for (size_t i = 0; i < records.size(); ++i) {
    const std::string* op = records[i].field("op");
    if (op != nullptr && op->size() == 1 && (*op)[0] == 0x05 && records[i].field("compression") &&
        records[i].field("size") && records[i].field("size")->size() == 4) {
      chunks.push_back(i);
    }
  }
  if (chunks.empty()) return false;
  BagRecord& c = records[chunks[pick(rng, chunks.size())]];
  using formats::Codec;
  const std::string& name = *c.field("compression");
  Codec codec = name == "bz2" ? Codec::kBz2 : name == "lz4" ? Codec::kLz4Frame : Codec::kNone;
  const size_t others = bag.size() - c.data.size();
  if (others >= max_size) return false;
  std::vector<uint8_t> packed;
  uint64_t declared = 0;
  if (!mutate_chunk(rng, codec, c.data, get32(reinterpret_cast<const uint8_t*>(c.field("size")->data())), 0xffffffff,
                    {Codec::kNone, Codec::kBz2, Codec::kLz4Frame}, max_size - others, packed, declared)) {
    return false;
  }
  c.data = std::move(packed);
  *c.field("compression") = codec == Codec::kBz2 ? "bz2" : codec == Codec::kLz4Frame ? "lz4" : "none";
  std::string size(4, '\0');
  for (int i = 0; i < 4; ++i) size[static_cast<size_t>(i)] = static_cast<char>(declared >> (8 * i));
  *c.field("size") = size;
  out.clear();
  write_bag(records, tail, out);
  return out.size() <= max_size;
}

// --- MCAP ------------------------------------------------------------------------------------------------------

/// Mutates one chunk of an MCAP file (the bytes after its magic) into `out`; false when there is none to mutate.
/// A record: opcode, u64 length, body; a chunk's body: start and end time, uncompressed size (u64), uncompressed
/// CRC (u32), compression (u32 length, text), records (u64 length, bytes).
inline bool mutate_mcap(Rng& rng, std::span<const uint8_t> m, size_t max_size, std::vector<uint8_t>& out) {
  struct Chunk {
    size_t at, end, records_at;
    uint64_t records_len, declared;
    std::string compression;
  };
  std::vector<Chunk> chunks;
  for (size_t p = 0; p + 9 <= m.size();) {
    // A chunk cut short by the end of the input (a seed is a file's first bytes) keeps what there is.
    const uint64_t len = std::min<uint64_t>(get64(&m[p + 1]), m.size() - p - 9);
    const size_t body = p + 9, end = body + static_cast<size_t>(len);
    if (m[p] == 0x06 && len >= 8 + 8 + 8 + 4 + 4) {
      const uint32_t clen = get32(&m[body + 28]);
      const size_t after = body + 32 + clen;
      if (clen <= len - 32 && end - after >= 8) {
        const uint64_t rlen = std::min<uint64_t>(get64(&m[after]), end - after - 8);
        {
          chunks.push_back({p, end, after + 8, rlen, get64(&m[body + 16]),
                            std::string(reinterpret_cast<const char*>(&m[body + 32]), clen)});
        }
      }
    }
    p = end;
  }
  if (chunks.empty()) return false;
  const Chunk& c = chunks[pick(rng, chunks.size())];
  using formats::Codec;
  Codec codec = c.compression == "zstd" ? Codec::kZstd : c.compression == "lz4" ? Codec::kLz4Frame : Codec::kNone;
  const size_t others = m.size() - static_cast<size_t>(c.records_len);
  if (others >= max_size) return false;
  std::vector<uint8_t> packed;
  uint64_t declared = 0;
  if (!mutate_chunk(rng, codec, m.subspan(c.records_at, static_cast<size_t>(c.records_len)), c.declared, ~uint64_t{0},
                    {Codec::kNone, Codec::kZstd, Codec::kLz4Frame}, max_size - others, packed, declared)) {
    return false;
  }
  const std::string compression = codec == Codec::kZstd ? "zstd" : codec == Codec::kLz4Frame ? "lz4" : "";
  std::vector<uint8_t> body(m.begin() + static_cast<ptrdiff_t>(c.at + 9),
                            m.begin() + static_cast<ptrdiff_t>(c.at + 25));
  put64(body, declared);
  // The CRC: cleared (0: not checked) or kept (now wrong whenever the records changed).
  const uint32_t crc = pick(rng, 2) == 0 ? 0 : get32(&m[c.at + 9 + 24]);
  put32(body, crc);
  put32(body, static_cast<uint32_t>(compression.size()));
  body.insert(body.end(), compression.begin(), compression.end());
  put64(body, packed.size());
  body.insert(body.end(), packed.begin(), packed.end());
  out.assign(m.begin(), m.begin() + static_cast<ptrdiff_t>(c.at));
  out.push_back(0x06);
  put64(out, body.size());
  out.insert(out.end(), body.begin(), body.end());
  out.insert(out.end(), m.begin() + static_cast<ptrdiff_t>(c.end), m.end());
  return out.size() <= max_size;
}

// --- ROS message definitions -----------------------------------------------------------------------------------

/// A definition of fuzz_msgs/Root built to nest or repeat types, within max_size bytes.
inline std::string nested_definition(Rng& rng, size_t max_size) {
  const std::string sep = std::string(80, '=') + "\n";
  const char* kinds[] = {"int32", "float64", "string", "uint8[]", "float32[3]"};
  auto type_name = [](size_t i) { return "fuzz_msgs/T" + std::to_string(i); };
  auto array = [&]() -> std::string {
    switch (pick(rng, 4)) {
      case 0: return "[]";
      case 1: return "[" + std::to_string(pick(rng, 5)) + "]";
      case 2: return "[<=" + std::to_string(pick(rng, 5)) + "]";
      default: return "";
    }
  };
  std::string d = type_name(0) + array() + " t\n" + kinds[pick(rng, 5)] + " x\n";
  const size_t levels = 1 + pick(rng, 200);  // the readers refuse nesting past 64
  const uint64_t shape = pick(rng, 4);
  for (size_t i = 0; i < levels && d.size() + 200 < max_size; ++i) {
    d += sep + "MSG: " + type_name(i) + "\n";
    if (shape == 0 || i + 1 < levels) {
      d += type_name(i + 1) + array() + " next\n";  // a chain: each holds the next (the last one undefined)
    }
    if (shape == 1 && pick(rng, 8) == 0) d += type_name(pick(rng, i + 1)) + array() + " back\n";  // a cycle
    if (shape == 2 && pick(rng, 4) == 0) {  // the same type defined again, maybe differently
      d += sep + "MSG: " + type_name(pick(rng, i + 1)) + "\n" + kinds[pick(rng, 5)] + " again\n";
    }
    d += std::string(kinds[pick(rng, 5)]) + " v" + std::to_string(i) + "\n";
  }
  return d;
}

}  // namespace driftlab::fuzz
