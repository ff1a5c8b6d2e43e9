// Per-channel timing: rate, drops (sequence gaps, gaps in the period), bursts, duplicates, reordering, stamps
// (zero, frozen, late), latency and the source clock's offset and drift with confidence intervals, and the
// verdict in words. Internal to analyzers (used by timing.cc).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

/// The timing of one channel from its samples (whose stamps it borrows for a moment: they are restored), the
/// clock fitted from log_start [us].
/// to_arrival, when given, maps the channel's stamps onto the recorder's clock (its clock domain's mapping): its
/// latency, period, gaps and clock are then judged on that clock, its median stamp on its own.
ChannelTiming channel_timing(const std::string& name, Samples& s, int64_t log_start,
                             const std::function<int64_t(int64_t)>& to_arrival = {});

/// Whether the channel is a result written at once (ChannelTiming::written_at_once): its stamps span 10 s or more
/// and its arrivals under 1% of that. A stream sent as it is made arrives over as long as its stamps span.
bool written_at_once(const Samples& s);

/// Adds a reason to a channel's verdict: a fault, or a warning (which leaves a fault a fault), and what it says is
/// wrong.
void add_reason(ChannelTiming& c, bool fault, const std::string& why, Cause cause);

/// Orders a channel's reasons cause before symptom (a stable sort by Cause), once all are added.
void order_reasons(ChannelTiming& c);

}  // namespace driftlab::analyzers::internal
