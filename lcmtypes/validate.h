// Checks an encoded driftlab message against its type's layout before any decoder sees it: every array and string
// length non-negative and inside the message, the message ending exactly where its type says. lcm-gen's decoders
// trust lengths (a negative one throws std::length_error, a huge one allocates gigabytes), so every decode of
// untrusted bytes (logs, the bus) goes through decode() here. The layouts come from lcmtypes/*.lcm (schema.h),
// compiled once into plans. Thread-safety: safe from any thread.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "core/bus.h"

namespace driftlab::lcmtypes {

/// Why an encoded message does not hold a well-formed message of a known driftlab type ("ranges: length -5",
/// "40 bytes, shorter than its type"), or nullopt when it does. Messages of types driftlab does not know (other
/// fingerprints) have no layout to check: nullopt.
std::optional<std::string> layout_problem(std::span<const uint8_t> data);

/// Whether data is a well-formed message of the driftlab type with this fingerprint.
bool well_formed(std::span<const uint8_t> data, int64_t fingerprint);

/// Decodes data as T when it is a well-formed T; false (out unspecified) otherwise. Never throws.
template <typename T>
bool decode(std::span<const uint8_t> data, T& out) {
  if (!well_formed(data, T::getHash())) return false;
  try {
    return out.decode(data.data(), 0, static_cast<int>(data.size())) >= 0;
  } catch (...) {  // not reached after the check; kept so no decoder exception can escape
    return false;
  }
}

}  // namespace driftlab::lcmtypes

namespace driftlab {

/// Decodes a bus message as T when it is a well-formed T (lcmtypes::decode); false for other types, short or
/// malformed bytes. Modules decode every input with it.
template <typename T>
bool decode_message(const BusMessage& m, T& out) {
  return lcmtypes::decode(m.data, out);
}

}  // namespace driftlab
