// Per-channel timing: rate, drops (sequence gaps, gaps in the period), bursts, duplicates, reordering, stamps
// (zero, frozen, late), latency and the source clock's offset and drift with confidence intervals, and the
// verdict in words. Internal to analyzers (used by timing.cc).
#pragma once

#include <cstdint>
#include <string>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

/// The timing of one channel from its samples (whose stamps it borrows for a moment: they are restored), the
/// clock fitted from log_start [us].
ChannelTiming channel_timing(const std::string& name, Samples& s, int64_t log_start);

}  // namespace driftlab::analyzers::internal
