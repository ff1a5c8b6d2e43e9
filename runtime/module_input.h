// What a module does with a message the host hands it: decode it only when it holds its type's layout
// (lcmtypes/validate.h), and drop and count the inputs whose numbers are NaN, infinite or beyond any robot's
// (NonFiniteInputs, for the module's statistics). Every module decodes its inputs through here.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "lcmtypes/validate.h"
#include "runtime/bus.h"

namespace driftlab {

/// Decodes a bus message as T when it is a well-formed T (lcmtypes::decode); false for other types, short or
/// malformed bytes. Modules decode every input with it.
template <typename T>
bool decode_message(const BusMessage& m, T& out) {
  return lcmtypes::decode(m.data, out);
}

/// The inputs a module drops because a number in them is NaN, infinite (lcmtypes::non_finite) or out of range (not
/// plausible, or a value the module derives), counted with the first one named, for the module's statistics. Not
/// thread-safe (one module).
class NonFiniteInputs {
 public:
  /// Whether m's numbers are all finite; counts m (naming the first) when not.
  bool finite(const BusMessage& m);
  /// Whether a value the module uses is plausible; counts the input (naming field and value) when not.
  bool plausible(std::string_view channel, const char* field, double v);
  /// Counts an input the module found unusable itself: what names the value ("the yaw of orientation = nan").
  void count(std::string_view channel, const std::string& what);
  int64_t dropped() const { return dropped_; }
  /// "N inputs with NaN, infinite or out-of-range numbers dropped (first: ODOM: linear_velocity.x = nan)", prefixed
  /// with "MODULE: "; nullopt when none were.
  std::optional<std::string> warning(const std::string& module) const;

 private:
  int64_t dropped_ = 0;
  std::string first_;
};

}  // namespace driftlab
