// The LCM event-log format (see docs/log-format.md): a sequence of events, each
//   uint32 sync (0xEDA1DA01) | int64 event number | int64 timestamp [us] | int32 channel length |
//   int32 data length | channel bytes (no terminator) | data bytes
// with every integer big-endian.
#pragma once

#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>

namespace driftlab::logfmt {

inline constexpr uint32_t kSyncWord = 0xEDA1DA01u;
inline constexpr size_t kEventHeaderSize = 4 + 8 + 8 + 4 + 4;  // 28 bytes
/// Longest channel name the reader accepts; longer ones are treated as corruption.
/// (LCM itself cannot publish channels longer than 63 bytes.)
inline constexpr int32_t kMaxChannelLength = 1023;
/// Longest channel name the writer produces.
inline constexpr int32_t kMaxWriteChannelLength = 255;

inline uint32_t load_be32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return __builtin_bswap32(v);
}
inline uint64_t load_be64(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, 8);
  return __builtin_bswap64(v);
}
inline void store_be32(uint8_t* p, uint32_t v) {
  v = __builtin_bswap32(v);
  std::memcpy(p, &v, 4);
}
inline void store_be64(uint8_t* p, uint64_t v) {
  v = __builtin_bswap64(v);
  std::memcpy(p, &v, 8);
}

/// Writes the 28-byte event header into out.
inline void encode_event_header(uint8_t* out, int64_t event_number, int64_t utime, int32_t channel_len,
                                int32_t data_len) {
  store_be32(out, kSyncWord);
  store_be64(out + 4, static_cast<uint64_t>(event_number));
  store_be64(out + 12, static_cast<uint64_t>(utime));
  store_be32(out + 20, static_cast<uint32_t>(channel_len));
  store_be32(out + 24, static_cast<uint32_t>(data_len));
}

/// The LCM type fingerprint: the first 8 bytes of an encoded LCM message, or 0 when shorter.
inline int64_t fingerprint(std::span<const uint8_t> data) {
  return data.size() >= 8 ? static_cast<int64_t>(load_be64(data.data())) : 0;
}

}  // namespace driftlab::logfmt
