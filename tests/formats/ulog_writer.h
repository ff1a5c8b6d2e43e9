// A PX4 flight log (ULog) written record by record, for tests of the reader, the import and the flight-log
// diagnosis: the header, flag bits, formats, information fields, subscriptions, data, logged strings and dropouts,
// little-endian as PX4's "ULog File Format" lays them out.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace driftlab::test {

/// v little-endian in `bytes` bytes.
inline void put(std::vector<uint8_t>& b, uint64_t v, int bytes) {
  // Little-endian, zero past the value's 8 bytes (a wider field's padding).
  for (int i = 0; i < bytes; ++i) b.push_back(i < 8 ? static_cast<uint8_t>(v >> (8 * i)) : uint8_t{0});
}
inline std::vector<uint8_t> f32(float v) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  std::vector<uint8_t> b;
  put(b, u, 4);
  return b;
}

struct Ulog {
  std::vector<uint8_t> b;
  explicit Ulog(uint64_t start_us = 1000) {
    for (const int c : {0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35})
      b.push_back(static_cast<uint8_t>(c));  // "ULog", 01 12 35
    b.push_back(1);
    put(b, start_us, 8);
  }
  void record(char type, const std::vector<uint8_t>& body) {
    put(b, body.size(), 2);
    b.push_back(static_cast<uint8_t>(type));
    b.insert(b.end(), body.begin(), body.end());
  }
  void flags(uint8_t incompat0, uint64_t appended = 0, uint8_t incompat_other = 0) {
    std::vector<uint8_t> r(16, 0);
    r[8] = incompat0;
    r[9] = incompat_other;
    put(r, appended, 8);
    put(r, 0, 16);
    record('B', r);
  }
  void format(const std::string& text) { record('F', {text.begin(), text.end()}); }
  void info(const std::string& key, const std::vector<uint8_t>& value) {
    std::vector<uint8_t> r{static_cast<uint8_t>(key.size())};
    r.insert(r.end(), key.begin(), key.end());
    r.insert(r.end(), value.begin(), value.end());
    record('I', r);
  }
  void subscribe(uint8_t multi, uint16_t id, const std::string& name) {
    std::vector<uint8_t> r{multi};
    put(r, id, 2);
    r.insert(r.end(), name.begin(), name.end());
    record('A', r);
  }
  /// A data message: its msg_id, then the bytes as its format lays them out.
  size_t data_bytes(uint16_t id, const std::vector<uint8_t>& bytes) {
    std::vector<uint8_t> r;
    put(r, id, 2);
    r.insert(r.end(), bytes.begin(), bytes.end());
    const size_t at = b.size();
    record('D', r);
    return at;
  }
  /// A data message of format "t:uint64_t timestamp;float x;".
  size_t data(uint16_t id, uint64_t t, float x) {
    std::vector<uint8_t> r;
    put(r, id, 2);
    put(r, t, 8);
    const auto v = f32(x);
    r.insert(r.end(), v.begin(), v.end());
    const size_t at = b.size();
    record('D', r);
    return at;
  }
  void logged(char level, uint64_t t, const std::string& text) {
    std::vector<uint8_t> r{static_cast<uint8_t>(level)};
    put(r, t, 8);
    r.insert(r.end(), text.begin(), text.end());
    record('L', r);
  }
  void dropout(uint16_t ms) {
    std::vector<uint8_t> r;
    put(r, ms, 2);
    record('O', r);
  }
};

}  // namespace driftlab::test
