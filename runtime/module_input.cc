#include "runtime/module_input.h"

#include <cstdio>

namespace driftlab {

bool NonFiniteInputs::finite(const BusMessage& m) {
  const auto what = lcmtypes::non_finite(m.data);
  if (what) count(m.channel, *what);
  return !what;
}

bool NonFiniteInputs::plausible(std::string_view channel, const char* field, double v) {
  if (driftlab::plausible(v)) return true;
  char what[96];
  std::snprintf(what, sizeof(what), "%s = %g, beyond %g", field, v, kMaxMagnitude);
  count(channel, what);
  return false;
}

void NonFiniteInputs::count(std::string_view channel, const std::string& what) {
  if (dropped_++ == 0) first_ = std::string(channel) + ": " + what;
}

std::optional<std::string> NonFiniteInputs::warning(const std::string& module) const {
  if (dropped_ == 0) return std::nullopt;
  return module + ": " + std::to_string(dropped_) + " input" + (dropped_ == 1 ? "" : "s") +
         " with NaN, infinite or out-of-range numbers dropped (first: " + first_ + ")";
}

}  // namespace driftlab
