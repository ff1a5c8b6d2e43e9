// The ranges of `driftlab diagnose`'s options, which the command and the Python module (python/) check alike.
#pragma once

#include "core/config.h"

namespace driftlab::apps {

/// The ranges of diagnose's --max-lag and --window [s].
inline constexpr config::Range kMaxLagRange = config::above(0, 10);
inline constexpr config::Range kWindowRange = config::above(0, 86400);

}  // namespace driftlab::apps
