// Decompression of whole blocks (bag chunks) with Debian's libbz2, liblz4 and zlib. A block cut short or
// corrupt still gives every byte decoded before the damage, so the intact messages in it can be read.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace driftlab::formats::internal {

enum class Codec { kNone, kBz2, kLz4Frame, kGzip };

/// Decompresses in into out (cleared first; expected_size is a hint, 0 when unknown). Returns an empty string on
/// success, or what went wrong ("bz2: data integrity error"); out then holds what was decoded before it.
std::string decompress(Codec codec, std::span<const uint8_t> in, size_t expected_size, std::vector<uint8_t>& out);

}  // namespace driftlab::formats::internal
