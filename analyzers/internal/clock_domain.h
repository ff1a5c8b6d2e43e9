// Clock domains: which streams' stamps share a clock, and how that clock runs against the recorder's (the log's
// event times). A Gazebo run recorded with use_sim_time stamps every stream with simulation time while the bag's
// times are the wall clock's: a stream is judged against its own domain's mapping to arrival (for simulation time,
// the real-time factor, which varies during a run), and against its peers on that clock; the domain's rate is a
// property of the recording, reported once.
// Internal to analyzers (used by timing.cc). Thread-safety: plain values.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

/// A stream taking part in the domains' search.
struct DomainStream {
  std::string name;
  const Samples* samples = nullptr;  ///< with a header
  bool is_tf = false;                ///< transforms: their stamps may be post-dated on purpose (AMCL's), so they
                                     ///< are not the domain's reference when other streams are there
  bool is_clock = false;             ///< a simulator's clock (/clock): its stamps are the clock's own time, sent
                                     ///< as it ticks, so it is its domain's reference where it is recorded
};

/// Whether a channel of this source type (CHANNEL_SOURCES) is a simulator's clock: rosgraph_msgs/Clock, ROS 1's
/// name or ROS 2's.
bool is_clock_source(const std::string& source_type);

/// The domains found and each one's mapping from stamps to the recorder's clock.
class ClockDomains {
 public:
  /// Groups the streams by clock and fits each foreign clock's mapping. log_start and log_end bound the arrivals.
  static ClockDomains find(const std::vector<DomainStream>& in, int64_t log_start, int64_t log_end);

  const std::vector<ClockDomain>& domains() const { return domains_; }
  /// The domain of a channel (an index into domains()), or -1 when it has none (no header, stamps unset).
  int domain_of(const std::string& channel) const;
  /// A stamp of the channel's clock as the recorder's clock would read at the same instant, delivered as fast as
  /// its domain's fastest stream [us]: the stamp itself for streams on the recorder's clock.
  int64_t to_arrival(const std::string& channel, int64_t stamp) const { return to_arrival(domain_of(channel), stamp); }
  /// The same for a stamp of a domain's clock (domain as domain_of gives it): for a channel's many stamps, its domain
  /// found once.
  int64_t to_arrival(int domain, int64_t stamp) const;
  /// How much later than its domain's reference the channel's messages arrive [s]: the median over windows of its
  /// fastest delivery above the reference's. NaN without a reference to compare with.
  double peer_delay_s(const std::string& channel) const;

 private:
  struct Mapping {
    bool identity = true;
    std::vector<std::array<double, 2>> knots;  ///< (stamp [us], arrival - stamp [us]), by stamp
    double at(double stamp) const { return mapped_offset_s(knots, stamp); }  ///< the same units as the knots
  };
  std::vector<ClockDomain> domains_;
  std::vector<Mapping> mappings_;
  std::map<std::string, int, std::less<>> channel_domain_;
  std::map<std::string, double, std::less<>> peer_delay_s_;
};

/// The verdicts that need every stream's clock: a stream stamped on another clock than its peers (the wrong time
/// base: an IMU on the wall clock among streams on simulation time), a recording all on a clock set wrong (GPS time,
/// TAI, a time zone), a stream arriving later than its peers on a clock of its own (where latency has no absolute
/// zero), and each transform received older than one before it (reordered).
void judge_domains(Diagnosis& d);

/// A stream on a clock judged as stamped (the recorder's, or one set wrong by a constant) arriving 10 ms or more
/// after the typical stream on it (a camera or lidar: a period of its own more), where no other finding already
/// says it is late (the command loop's delay). After the loops are judged.
void judge_late_streams(Diagnosis& d);

}  // namespace driftlab::analyzers::internal
