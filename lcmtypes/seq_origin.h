// Where a channel's header.seq comes from (driftlab.channel_source_t's seq_origin): LCM definitions hold no
// constants that driftlab's schema reader takes, so the values are named here, with the channel they travel on.
#pragma once

#include <cstdint>

namespace driftlab::lcmtypes {

/// The channel an import writes one driftlab.channel_source_t on per channel, before the channel's first message.
inline constexpr char kChannelSources[] = "CHANNEL_SOURCES";

enum class SeqOrigin : int8_t {
  kSource = 0,     ///< the publisher's own count (ROS 1 header.seq): a gap is a lost message
  kTransport = 1,  ///< a transport's or recorder's count per channel (MCAP's sequence)
  kCounted = 2,    ///< none travelled: the import counted the messages, so seq has no gaps
};

}  // namespace driftlab::lcmtypes
