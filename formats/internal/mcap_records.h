// MCAP's records as the reader and the writer share them (mcap.dev/spec): the magic, the opcodes, little-endian
// fields read with bounds checks, and the CRC MCAP asks for. Internal to formats/ (mcap.cc, mcap_read.cc,
// mcap_writer.cc).
#pragma once

#include <isa-l/crc.h>

#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "formats/compression.h"
#include "formats/mcap.h"

namespace driftlab::formats {
namespace mcap {

constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
enum Op : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};
constexpr size_t kRecordHead = 9;      // opcode + uint64 length
constexpr size_t kFooterContent = 20;  // summary_start, summary_offset_start, summary_crc

/// CRC-32 (zlib's, as MCAP asks) by Intel's ISA-L (Debian's libisal), which folds with the CPU's carry-less
/// multiply, 512 bits at a time where the CPU has VPCLMULQDQ: 10.5 GB/s here on a 4 MiB buffer, against 4.3 for
/// libdeflate 1.14 and 1.4 for zlib 1.2 in the same run (with libdeflate, the CRCs of the records and of the data
/// section were 8% of a zstd MCAP import's CPU time). zlib still combines.
inline uint32_t crc32_of(std::span<const uint8_t> b, uint32_t crc = 0) {
  return crc32_gzip_refl(crc, b.data(), b.size());
}

template <typename T>
inline T le(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;  // MCAP is little endian, as is every machine driftlab builds for (checked below)
}
static_assert(std::endian::native == std::endian::little, "MCAP's integers are read in place");

/// A cursor over a record's content; every read checks the bounds, and a failed read makes the cursor bad.
class Fields {
 public:
  explicit Fields(std::span<const uint8_t> b) : b_(b) {}
  bool ok() const { return ok_; }
  size_t pos() const { return pos_; }
  size_t left() const { return b_.size() - pos_; }
  template <typename T>
  T get() {
    if (!need(sizeof(T))) return T{};
    T v = le<T>(b_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }
  std::string_view str() {
    const uint32_t n = get<uint32_t>();
    if (!need(n)) return {};
    std::string_view s(reinterpret_cast<const char*>(b_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  std::span<const uint8_t> bytes(uint64_t n) {
    if (!need(n)) return {};
    auto s = b_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  std::vector<std::pair<std::string, std::string>> string_map() {
    std::vector<std::pair<std::string, std::string>> m;
    const uint32_t n = get<uint32_t>();
    if (!need(n)) return m;
    Fields inner(b_.subspan(pos_, n));
    pos_ += n;
    while (inner.ok() && inner.left() > 0) {
      std::string k(inner.str());
      std::string v(inner.str());
      if (inner.ok()) m.emplace_back(std::move(k), std::move(v));
    }
    if (!inner.ok()) ok_ = false;
    return m;
  }
  /// Skips a Map or Array (uint32 byte length, then the entries).
  void skip_sized() {
    const uint32_t n = get<uint32_t>();
    bytes(n);
  }

 private:
  bool need(uint64_t n) {
    if (!ok_ || n > left()) {
      ok_ = false;
      return false;
    }
    return true;
  }
  std::span<const uint8_t> b_;
  size_t pos_ = 0;
  bool ok_ = true;
};

inline std::string hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%08x", v);
  return buf;
}

/// What a reader keeps from read to read: the schemas and channels met, and a decompressor.
struct ReaderState {
  std::map<uint16_t, std::unique_ptr<McapSchema>> schemas;
  std::map<uint16_t, std::unique_ptr<McapChannel>> channels;
  Decompressor decompressor;  // the reading half's, when the read is not pipelined (workers have their own)
};

}  // namespace mcap

struct McapReader::Impl : mcap::ReaderState {};

}  // namespace driftlab::formats
