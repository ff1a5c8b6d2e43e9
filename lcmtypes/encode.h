// An LCM message encoded by its lcm-gen class, as the bytes of a log event or a bus message.
#pragma once

#include <cstdint>
#include <vector>

namespace driftlab::lcmtypes {

/// encode() into *out, whose memory is kept from one message to the next (a converter's hot loop).
template <typename T>
void encode_into(const T& m, std::vector<uint8_t>* out) {
  out->resize(static_cast<size_t>(m.getEncodedSize()));
  m.encode(out->data(), 0, static_cast<int>(out->size()));
}

template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> b;
  encode_into(m, &b);
  return b;
}

}  // namespace driftlab::lcmtypes
