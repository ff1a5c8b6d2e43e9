// Recognises driftlab message types by their LCM fingerprint (the first 8 bytes of every encoded message).
// The table is generated from lcmtypes/*.lcm at build time. Thread-safety: read-only, safe everywhere.
#pragma once

#include <cstdint>
#include <span>

namespace driftlab::lcmtypes {

struct TypeInfo {
  int64_t fingerprint;
  const char* name;  ///< "driftlab.imu_t"
  bool has_header;   ///< the message starts with driftlab.header_t (a stream message)
};

/// Every driftlab message type.
std::span<const TypeInfo> all_types();

/// The type with this fingerprint, or nullptr when unknown.
const TypeInfo* find_type(int64_t fingerprint);

/// The full name of the type with this fingerprint ("driftlab.imu_t"), or nullptr when unknown.
const char* type_name(int64_t fingerprint);

}  // namespace driftlab::lcmtypes
