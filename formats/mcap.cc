// MCAP, written from the specification (mcap.dev/spec): "\x89MCAP0\r\n", then records, each
//   uint8 opcode, uint64 content length, content;
// little-endian integers, strings and maps prefixed with a uint32 byte length. The data section ends with Data End
// (0x0F, a CRC of every byte before it); the optional summary repeats schemas and channels and indexes the chunks;
// the Footer (0x02) points at the summary and carries its CRC; the magic closes the file.
// This file: opening a file as MCAP; reading it is mcap_read.cc, writing mcap_writer.cc, the records they share
// formats/internal/mcap_records.h.
#include "formats/mcap.h"

#include <cstring>

#include "formats/internal/mcap_records.h"

namespace driftlab::formats {

using namespace mcap;  // NOLINT(google-build-using-namespace): the records' own names, in the files that read them

McapReader::McapReader() : impl_(std::make_unique<Impl>()) {}
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;
McapReader::~McapReader() = default;

bool McapReader::looks_like(std::span<const uint8_t> head) {
  return head.size() >= 5 && std::memcmp(head.data(), kMagic, 5) == 0;
}

Result<McapReader> McapReader::check(const std::string& name, std::span<const uint8_t> bytes) {
  if (!looks_like(bytes)) return Error(name + ": not an MCAP file (no MCAP magic)");
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    return Error(name + ": MCAP major version " + std::string(1, static_cast<char>(bytes.size() > 5 ? bytes[5] : '?')) +
                 " is not supported (0 is)");
  }
  McapReader r;
  r.bytes_ = bytes;
  return r;
}

Result<McapReader> McapReader::open(const std::string& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  auto r = check(path, file->bytes());
  if (r) r->file_ = std::move(*file);
  return r;
}

Result<McapReader> McapReader::from_memory(std::span<const uint8_t> bytes) { return check("mcap", bytes); }

void McapReader::set_pipelined(bool on) { pipelined_ = on; }

}  // namespace driftlab::formats
