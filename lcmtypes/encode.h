// An LCM message encoded by its lcm-gen class, as the bytes of a log event or a bus message.
#pragma once

#include <cstdint>
#include <vector>

namespace driftlab::lcmtypes {

template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

}  // namespace driftlab::lcmtypes
