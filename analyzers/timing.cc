// The timing diagnosis: one pass over the log keeps each channel's samples (analyzers/internal/channel_samples.h),
// then each concern has its file: per-channel timing (channel_timing.cc), skew between streams (stream_skew.cc)
// and the TF tree (tf_check.cc).
#include "analyzers/timing.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/internal/channel_timing.h"
#include "analyzers/internal/clock_domain.h"
#include "analyzers/internal/command_loop.h"
#include "analyzers/internal/stream_skew.h"
#include "analyzers/internal/tf_check.h"
#include "analyzers/internal/timesync_check.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "driftlab/physics_step_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "lcmtypes/seq_origin.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {

Result<Diagnosis> diagnose(const std::string& log, const DiagnoseOptions& options) {
  ReadOptions read{.channels = options.channels, .also = options.ignore_channels, .on_problem = {}};
  auto reader = LogReader::open(log, read);
  if (!reader) return reader.error();
  Diagnosis d;
  d.log = log;
  std::map<std::string, internal::Samples, std::less<>> channels;
  internal::TfCheck tf;
  internal::CommandLoopCheck loops;
  internal::TimesyncCheck timesync;
  const int64_t timesync_hash = driftlab::timesync_status_t::getHash();
  const int64_t tf_hash = driftlab::tf_t::getHash();
  const int64_t trajectory_hash = driftlab::joint_trajectory_t::getHash();
  const int64_t joint_state_hash = driftlab::joint_state_t::getHash();
  const int64_t physics_hash = driftlab::physics_step_t::getHash();
  const int64_t source_hash = driftlab::channel_source_t::getHash();
  std::map<std::string, driftlab::channel_source_t, std::less<>> sources;  // what an import said of each channel
  std::map<std::string, PhysicsTiming> physics;
  internal::Samples* last = nullptr;
  std::string_view last_name;
  Event e;
  bool first = true;
  while (reader->next(e)) {
    if (first) d.start_utime = d.end_utime = e.utime;
    first = false;
    d.start_utime = std::min(d.start_utime, e.utime);
    d.end_utime = std::max(d.end_utime, e.utime);
    if (last == nullptr || e.channel != last_name) {
      auto it = channels.find(e.channel);
      if (it == channels.end()) {
        it = channels.emplace(std::string(e.channel), internal::Samples{}).first;
        const lcmtypes::TypeInfo* type = lcmtypes::find_type(logfmt::fingerprint(e.data));
        it->second.type = type != nullptr ? type->name : "";
        // Other programs' types may carry our header too: recognise it by its shape.
        it->second.has_header = lcmtypes::has_header(e.data, e.utime);
      }
      last = &it->second;
      last_name = it->first;
    }
    internal::Samples& s = *last;
    if (!s.type.empty()) {
      if (auto why = lcmtypes::layout_problem(e.data)) {
        if (s.malformed++ == 0) s.malformed_example = *why;
        continue;
      }
    }
    const int64_t fp = logfmt::fingerprint(e.data);
    s.arrival.push_back(e.utime);
    if (fp == tf_hash) tf.add_tf(std::string(last_name), e.data, e.utime, internal::is_static_tf_channel(last_name));
    if (fp == trajectory_hash) loops.add_command(std::string(last_name), e.data, e.utime);
    if (fp == joint_state_hash) loops.add_state(std::string(last_name), e.data);
    // Not a bookkeeping channel's (ULOG_UTC: a GNSS receiver's time, not an exchange between two computers).
    if (fp == timesync_hash && std::find(options.ignore_channels.begin(), options.ignore_channels.end(), last_name) ==
                                   options.ignore_channels.end()) {
      timesync.add(std::string(last_name), e.data);
    }
    if (fp == source_hash) {
      driftlab::channel_source_t m;
      if (lcmtypes::decode(e.data, m)) sources[m.channel] = std::move(m);
    }
    if (fp == physics_hash) {
      driftlab::physics_step_t m;
      if (lcmtypes::decode(e.data, m) && m.real_time_factor > 0 && std::isfinite(m.real_time_factor)) {
        PhysicsTiming& p = physics[std::string(last_name)];
        p.channel = last_name;
        p.real_time_factor_mean = (p.real_time_factor_mean * static_cast<double>(p.messages) + m.real_time_factor) /
                                  static_cast<double>(p.messages + 1);
        p.real_time_factor_min =
            p.messages == 0 ? m.real_time_factor : std::min(p.real_time_factor_min, m.real_time_factor);
        p.sim_step_s = m.sim_step_s;
        p.wall_step_max_s = std::max(p.wall_step_max_s, m.wall_step_max_s);
        ++p.messages;
      }
    }
    if (s.has_header) {
      if (const auto h = lcmtypes::read_header(e.data, e.utime)) {
        s.seq.push_back(h->seq);
        s.stamp.push_back(h->utime);
        if (s.stamp.size() == 1) s.frame.assign(h->frame_id);
        internal::add_motion(s, fp, e.data);
      } else {
        // An unknown type whose header was a coincidence, or a message too short for one: the channel is untyped.
        s.has_header = false;
        s.seq.clear();
        s.stamp.clear();
      }
    }
    if (!s.has_header) {  // duplicates of untyped messages are told by their bytes
      uint64_t digest = e.data.size();
      for (size_t i = 0; i < std::min<size_t>(e.data.size(), 64); ++i) digest = (digest ^ e.data[i]) * 1099511628211ull;
      s.digest.push_back(digest);
    }
  }
  d.log_problems = reader->problems();

  auto ignored = [&](const std::string& name) {
    return std::find(options.ignore_channels.begin(), options.ignore_channels.end(), name) !=
           options.ignore_channels.end();
  };
  // Which clock each stream's stamps are on, and each foreign clock's mapping to the recorder's.
  std::vector<internal::DomainStream> streams;
  for (auto& [name, s] : channels) {
    d.flight_log = d.flight_log || name.starts_with("ULOG_");
    s.is_tf = s.type == "driftlab.tf_t";
    s.is_static_tf = s.is_tf && internal::is_static_tf_channel(name);
    const auto source = sources.find(name);
    if (source != sources.end()) {
      s.seq_counted = source->second.seq_origin == static_cast<int8_t>(lcmtypes::SeqOrigin::kCounted);
    }
    const bool is_clock = source != sources.end() && internal::is_clock_source(source->second.source_type);
    if (!ignored(name) && s.has_header && !s.is_static_tf && !internal::written_at_once(s)) {
      streams.push_back({name, &s, s.is_tf, is_clock});
    }
  }
  const internal::ClockDomains domains = internal::ClockDomains::find(streams, d.start_utime, d.end_utime);
  d.domains = domains.domains();
  auto to_arrival = [&](const std::string& channel, int64_t stamp) { return domains.to_arrival(channel, stamp); };
  for (auto& [name, s] : channels) {
    if (ignored(name)) continue;
    const int domain = domains.domain_of(name);
    std::function<int64_t(int64_t)> mapping;
    if (domain >= 0 && d.domains[static_cast<size_t>(domain)].mapped) {
      mapping = [&, channel = name](int64_t stamp) { return domains.to_arrival(channel, stamp); };
    }
    ChannelTiming c = internal::channel_timing(name, s, d.start_utime, mapping);
    c.domain = domain;
    c.peer_delay_s = domains.peer_delay_s(name);
    if (const auto it = sources.find(name); it != sources.end()) c.source_type = it->second.source_type;
    if (s.has_header && !s.is_tf && !c.written_at_once) tf.add_data(name, s.frame, s.stamp, s.arrival);
    d.channels.push_back(std::move(c));
  }
  d.tf = tf.finish(to_arrival);
  internal::judge_domains(d);
  // Skew between every two streams that observe the yaw rate: IMU gyro, wheel odometry, poses, scans.
  d.pairs = internal::stream_pairs(channels, d.start_utime, d.end_utime, options);
  d.command_loops = loops.finish(d.start_utime);
  for (const CommandLoop& l : d.command_loops) internal::judge_loop(l, d.channels);
  internal::judge_late_streams(d);
  d.timesync = timesync.finish(d.start_utime, d.channels);
  for (auto& c : d.channels) internal::order_reasons(c);
  for (auto& [name, p] : physics) d.physics.push_back(std::move(p));
  return d;
}

}  // namespace driftlab::analyzers
