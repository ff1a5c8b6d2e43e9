// Checks an encoded driftlab message against its type's layout before any decoder sees it: every array and string
// length non-negative and inside the message, the message ending exactly where its type says. lcm-gen's decoders
// trust lengths (a negative one throws std::length_error, a huge one allocates gigabytes), so every decode of
// untrusted bytes (logs, the bus) goes through decode() here. The layouts come from lcmtypes/*.lcm (schema.h),
// compiled once into plans. Thread-safety: safe from any thread.
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace driftlab::lcmtypes {

/// Why an encoded message does not hold a well-formed message of a known driftlab type ("ranges: length -5",
/// "40 bytes, shorter than its type"), or nullopt when it does. Messages of types driftlab does not know (other
/// fingerprints) have no layout to check: nullopt.
std::optional<std::string> layout_problem(std::span<const uint8_t> data);

/// The first number of a well-formed message of a driftlab type that is NaN or infinite, named by its field and
/// value ("linear_velocity.x = nan", "transforms[2].rotation.w = inf"), or nullopt. Scalars and fixed-size arrays
/// (covariances) are checked, in nested structs and in arrays of structs too; variable-length arrays of numbers
/// (ranges, points, intensities) are samples, where NaN and inf mean "no return", and are left to the module.
/// nullopt too for a malformed message or one of an unknown type.
std::optional<std::string> non_finite(std::span<const uint8_t> data);

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

/// Positions, speeds and rates beyond this [m, m/s, rad/s] are no robot's (past the Moon's orbit, faster than
/// light). The modules refuse them as they refuse NaN: below it, their arithmetic cannot overflow.
inline constexpr double kMaxMagnitude = 1e9;
/// Whether |v| <= kMaxMagnitude (false for NaN).
inline bool plausible(double v) { return v >= -kMaxMagnitude && v <= kMaxMagnitude; }

/// Whether a quaternion's norm is 1 within 1%, as a rotation's is: any quaternion printed with three decimals or more
/// passes. False for NaN and for squares that overflow. The one rule for poses: eval's readers
/// (analyzers/trajectory_io.h) and the modules use it.
inline bool unit_norm(double w, double x, double y, double z) {
  return std::abs(std::sqrt(w * w + x * x + y * y + z * z) - 1) <= 0.01;
}

}  // namespace driftlab
