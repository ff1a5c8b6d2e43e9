// Time synchronisation between two computers (driftlab.timesync_status_t, MAVROS's TimesyncStatus): the round trips,
// the estimated offset's course and its restarts, and what they mean for the streams stamped through it. Internal to
// analyzers (timing.cc feeds it in its one pass).
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

class TimesyncCheck {
 public:
  void add(const std::string& channel, std::span<const uint8_t> data);
  /// Each channel's timing, and its findings as reasons of the channel (a slow link, restarts).
  std::vector<TimesyncTiming> finish(int64_t start_utime, std::vector<ChannelTiming>& channels) const;

 private:
  struct Sample {
    int64_t stamp;
    double observed, estimated, round_trip;
  };
  std::map<std::string, std::vector<Sample>> samples_;
};

}  // namespace driftlab::analyzers::internal
