#include "analyzers/internal/timesync_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/internal/channel_timing.h"
#include "core/time.h"
#include "driftlab/timesync_status_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers::internal {
namespace {

// A step of the estimated offset this large between two estimates is the filter starting over: MAVROS's and PX4's
// filters move the estimate by a share of each exchange's disagreement (sub-millisecond on a working link) and
// reset it when an exchange disagrees by 100 ms or more; 10 ms is ten times a working link's step.
constexpr double kResyncStep_s = 0.010;
// A round trip over 10 ms (a 100 Hz stream's period) leaves the offset uncertain by up to half of it for every
// stream the companion restamps through it; PX4's and MAVROS's filters skip exchanges slower than that
// (max_rtt_sample, 10 ms), so a link whose typical round trip is over it barely updates its estimate.
constexpr double kSlowRoundTrip_s = 0.010;

}  // namespace

void TimesyncCheck::add(const std::string& channel, std::span<const uint8_t> data) {
  driftlab::timesync_status_t m;
  if (!lcmtypes::decode(data, m)) return;
  if (!std::isfinite(m.observed_offset_s) || !std::isfinite(m.estimated_offset_s) || !std::isfinite(m.round_trip_s)) {
    return;
  }
  samples_[channel].push_back({m.header.utime, m.observed_offset_s, m.estimated_offset_s, m.round_trip_s});
}

std::vector<TimesyncTiming> TimesyncCheck::finish(int64_t start_utime, std::vector<ChannelTiming>& channels) const {
  std::vector<TimesyncTiming> out;
  char buf[512];
  for (const auto& [name, s] : samples_) {
    TimesyncTiming t;
    t.channel = name;
    t.messages = static_cast<int64_t>(s.size());
    Array<double> rtt, residual;
    t.offset_first_s = s.front().estimated;
    t.offset_last_s = s.back().estimated;
    t.offset_min_s = t.offset_max_s = s.front().estimated;
    for (size_t i = 0; i < s.size(); ++i) {
      rtt.push_back(s[i].round_trip);
      residual.push_back(std::abs(s[i].observed - s[i].estimated));
      t.offset_min_s = std::min(t.offset_min_s, s[i].estimated);
      t.offset_max_s = std::max(t.offset_max_s, s[i].estimated);
      if (i > 0 && std::abs(s[i].estimated - s[i - 1].estimated) > kResyncStep_s) {
        ++t.resyncs;
        if (t.resync_at_s.size() < 10) {
          t.resync_at_s.push_back(Time::from_us(s[i].stamp).seconds_since(Time::from_us(start_utime)));
        }
      }
    }
    t.round_trip_s = distribution(std::move(rtt));
    t.residual_s = distribution(std::move(residual));
    const auto c = std::find_if(channels.begin(), channels.end(), [&](const auto& x) { return x.name == t.channel; });
    if (c != channels.end()) {
      if (t.round_trip_s.p50 > kSlowRoundTrip_s) {
        std::snprintf(buf, sizeof(buf),
                      "time sync round trips take %.1f ms (p50; p99 %.1f ms): every stamp converted through it is "
                      "uncertain by up to %.1f ms (a slow or busy link to the other computer)",
                      t.round_trip_s.p50 * 1e3, t.round_trip_s.p99 * 1e3, t.round_trip_s.p50 * 1e3 / 2);
        add_reason(*c, false, buf, Cause::kClock);
      }
      if (t.resyncs > 0) {
        std::snprintf(buf, sizeof(buf),
                      "time sync started over %lld times (the estimated offset stepped by more than %.0f ms; the "
                      "first at %.1f s): stamps converted through it jump there",
                      static_cast<long long>(t.resyncs), kResyncStep_s * 1e3, t.resync_at_s.front());
        add_reason(*c, true, buf, Cause::kClock);
      }
    }
    out.push_back(std::move(t));
  }
  return out;
}

}  // namespace driftlab::analyzers::internal
