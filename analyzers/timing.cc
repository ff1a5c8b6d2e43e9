// The timing diagnosis: one pass over the log (on a long log, a stretch of it per core, joined as one pass would
// have read them) keeps each channel's samples (analyzers/internal/channel_samples.h),
// then each concern has its file: per-channel timing (channel_timing.cc), skew between streams (stream_skew.cc)
// and the TF tree (tf_check.cc).
#include "analyzers/timing.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <thread>

#include "analyzers/internal/channel_samples.h"
#include "analyzers/internal/channel_timing.h"
#include "analyzers/internal/clock_domain.h"
#include "analyzers/internal/command_loop.h"
#include "analyzers/internal/stream_skew.h"
#include "analyzers/internal/tf_check.h"
#include "analyzers/internal/timesync_check.h"
#include "core/huge_page_allocator.h"
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

namespace {

using Channels = std::map<std::string, internal::Samples, std::less<>>;

/// What the pass keeps of the messages that are exchanges rather than samples of a stream: transforms, commands
/// and joint states, time syncs, what an import said of each channel, physics steps. Each takes them in log order.
struct Exchanges {
  explicit Exchanges(const DiagnoseOptions& o) : options(o) {}

  void add(int64_t fp, std::string_view channel, std::span<const uint8_t> data, int64_t utime) {
    if (fp == tf_hash) tf.add_tf(std::string(channel), data, utime, internal::is_static_tf_channel(channel));
    if (fp == trajectory_hash) loops.add_command(std::string(channel), data, utime);
    if (fp == joint_state_hash) loops.add_state(std::string(channel), data);
    // Not a bookkeeping channel's (ULOG_UTC: a GNSS receiver's time, not an exchange between two computers).
    if (fp == timesync_hash && std::find(options.ignore_channels.begin(), options.ignore_channels.end(), channel) ==
                                   options.ignore_channels.end()) {
      timesync.add(std::string(channel), data);
    }
    if (fp == source_hash) {
      driftlab::channel_source_t m;
      if (lcmtypes::decode(data, m)) sources[m.channel] = std::move(m);
    }
    if (fp == physics_hash) {
      driftlab::physics_step_t m;
      if (lcmtypes::decode(data, m) && m.real_time_factor > 0 && std::isfinite(m.real_time_factor)) {
        PhysicsTiming& p = physics[std::string(channel)];
        p.channel = channel;
        p.real_time_factor_mean = (p.real_time_factor_mean * static_cast<double>(p.messages) + m.real_time_factor) /
                                  static_cast<double>(p.messages + 1);
        p.real_time_factor_min =
            p.messages == 0 ? m.real_time_factor : std::min(p.real_time_factor_min, m.real_time_factor);
        p.sim_step_s = m.sim_step_s;
        p.wall_step_max_s = std::max(p.wall_step_max_s, m.wall_step_max_s);
        ++p.messages;
      }
    }
  }
  static bool is_exchange(int64_t fp) {
    return fp == tf_hash || fp == trajectory_hash || fp == joint_state_hash || fp == timesync_hash ||
           fp == source_hash || fp == physics_hash;
  }

  const DiagnoseOptions& options;
  internal::TfCheck tf;
  internal::CommandLoopCheck loops;
  internal::TimesyncCheck timesync;
  std::map<std::string, driftlab::channel_source_t, std::less<>> sources;
  std::map<std::string, PhysicsTiming> physics;
  static inline const int64_t timesync_hash = driftlab::timesync_status_t::getHash();
  static inline const int64_t tf_hash = driftlab::tf_t::getHash();
  static inline const int64_t trajectory_hash = driftlab::joint_trajectory_t::getHash();
  static inline const int64_t joint_state_hash = driftlab::joint_state_t::getHash();
  static inline const int64_t physics_hash = driftlab::physics_step_t::getHash();
  static inline const int64_t source_hash = driftlab::channel_source_t::getHash();
};

/// The pass over one stretch of the log: each channel's samples, and its exchanges, given to `exchanges` as they
/// come, or, for a stretch after the first (read on another thread), kept to be given in order after the
/// stretches before it.
struct Stretch {
  struct Exchange {
    int64_t fp;
    std::string_view channel;  // a key of channels
    size_t offset, size;       // in later_bytes
    int64_t utime;
  };

  void read(LogReader& reader) {
    // A log interleaves a few channels: the last ones met, found without the map (names are views of its keys).
    struct Recent {
      std::string_view name;
      internal::Samples* samples = nullptr;
    };
    std::array<Recent, 8> recent{};
    size_t next_slot = 0;
    internal::Samples* last = nullptr;
    std::string_view last_name;
    Event e;
    while (reader.next(e)) {
      if (!any) start_utime = end_utime = e.utime;
      any = true;
      start_utime = std::min(start_utime, e.utime);
      end_utime = std::max(end_utime, e.utime);
      if (last == nullptr || e.channel != last_name) {
        last = nullptr;
        for (const Recent& r : recent) {
          if (r.samples != nullptr && r.name == e.channel) {
            last = r.samples;
            last_name = r.name;
            break;
          }
        }
      }
      if (last == nullptr) {
        auto it = channels.find(e.channel);
        if (it == channels.end()) {
          it = channels.emplace(std::string(e.channel), internal::Samples{}).first;
          const lcmtypes::TypeInfo* type = lcmtypes::find_type(logfmt::fingerprint(e.data));
          it->second.type = type != nullptr ? type->name : "";
          // Other programs' types may carry our header too: recognise it by its shape.
          it->second.has_header = it->second.header_at_start = lcmtypes::has_header(e.data, e.utime);
        }
        last = &it->second;
        last_name = it->first;
        recent[next_slot] = {last_name, last};
        next_slot = (next_slot + 1) % recent.size();
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
      if (Exchanges::is_exchange(fp)) {
        if (exchanges != nullptr) {
          exchanges->add(fp, last_name, e.data, e.utime);
        } else {
          // Copied: the mapping behind the reader is released, and touching it again would fault it back in.
          later.push_back({fp, last_name, later_bytes.size(), e.data.size(), e.utime});
          later_bytes.insert(later_bytes.end(), e.data.begin(), e.data.end());
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
        for (size_t i = 0; i < std::min<size_t>(e.data.size(), 64); ++i)
          digest = (digest ^ e.data[i]) * 1099511628211ull;
        s.digest.push_back(digest);
      }
    }
  }

  /// Appends the stretch that follows this one, as if one pass had read both; false where this pass cannot tell
  /// what one pass would have found (a channel whose header was lost in one stretch and found in the other).
  bool append(Stretch& next) {
    if (next.any) {
      start_utime = any ? std::min(start_utime, next.start_utime) : next.start_utime;
      end_utime = any ? std::max(end_utime, next.end_utime) : next.end_utime;
      any = true;
    }
    for (auto& [name, b] : next.channels) {
      auto it = channels.find(name);
      if (it == channels.end()) {
        channels.emplace(name, std::move(b));
        continue;
      }
      if (!internal::append_samples(it->second, b)) return false;
    }
    for (const Exchange& x : next.later) {
      exchanges->add(x.fp, x.channel, std::span(next.later_bytes).subspan(x.offset, x.size), x.utime);
    }
    return true;
  }

  Channels channels;
  Exchanges* exchanges = nullptr;
  HugeVector<Exchange> later;
  HugeVector<uint8_t> later_bytes;
  size_t stretches = 1;  // read into this one
  bool any = false;
  int64_t start_utime = 0, end_utime = 0;
};

/// Stretches of at least this many bytes each are read on their own threads.
constexpr uint64_t kStretchBytes = 64ull << 20;

/// Reads the log in `parts` stretches, each on its own thread, into one pass whose exchanges go to `exchanges` in
/// log order; `readers` keeps the stretches' mappings (the pass keeps views of scans in them). Nothing where the
/// stretches cannot stand for one pass: a damaged log (one pass from the start finds and tells its problems), an
/// event across two stretches, or a channel that changes what it is between them.
std::optional<Stretch> read_in_stretches(const std::string& log, const ReadOptions& options, uint64_t parts,
                                         Exchanges& exchanges, std::vector<LogReader>& readers) {
  for (uint64_t k = 0; k < parts; ++k) {
    auto r = LogReader::open(log, options);
    if (!r) return std::nullopt;
    readers.push_back(std::move(*r));
  }
  const uint64_t size = readers[0].size_bytes();
  std::vector<uint64_t> bounds{0};
  for (uint64_t k = 1; k < parts; ++k) {
    const uint64_t at = readers[k].event_at_or_after(size / parts * k).value_or(size);
    if (at > bounds.back() && at < size) bounds.push_back(at);
  }
  bounds.push_back(size);
  const size_t n = bounds.size() - 1;
  std::vector<Stretch> stretches(n);
  stretches[0].exchanges = &exchanges;
  std::vector<std::thread> threads;
  for (size_t k = 0; k < n; ++k) readers[k].read_range(bounds[k], bounds[k + 1]);
  for (size_t k = 1; k < n; ++k) threads.emplace_back([&, k] { stretches[k].read(readers[k]); });
  stretches[0].read(readers[0]);
  for (auto& t : threads) t.join();
  for (size_t k = 0; k < n; ++k) {
    if (readers[k].problems() != 0 || readers[k].position() != bounds[k + 1]) return std::nullopt;
  }
  for (size_t k = 1; k < n; ++k) {
    if (!stretches[0].append(stretches[k])) return std::nullopt;
  }
  stretches[0].stretches = n;
  return std::move(stretches[0]);
}

}  // namespace

Result<Diagnosis> diagnose(const std::string& log, const DiagnoseOptions& options) {
  ReadOptions read{.channels = options.channels, .also = options.ignore_channels, .on_problem = {}};
  auto reader = LogReader::open(log, read);
  if (!reader) return reader.error();
  Diagnosis d;
  d.log = log;
  // Reading and checking each message is most of the time: on a long log, each core reads a stretch of it.
  const uint64_t cores = std::max(1u, std::thread::hardware_concurrency());
  const uint64_t parts = options.pass_threads > 0 ? static_cast<uint64_t>(options.pass_threads)
                                                  : std::min<uint64_t>(cores, reader->size_bytes() / kStretchBytes);
  std::optional<Exchanges> exchanges(std::in_place, options);
  std::vector<LogReader> stretch_readers;
  std::optional<Stretch> pass;
  if (parts > 1) pass = read_in_stretches(log, read, parts, *exchanges, stretch_readers);
  if (!pass) {  // one pass from the start
    stretch_readers.clear();
    exchanges.emplace(options);
    pass.emplace();
    pass->exchanges = &*exchanges;
    pass->read(*reader);
  }
  d.stretches = static_cast<int>(pass->stretches);
  d.log_problems = reader->problems();
  Channels& channels = pass->channels;
  internal::TfCheck& tf = exchanges->tf;
  const auto& sources = exchanges->sources;
  if (pass->any) {
    d.start_utime = pass->start_utime;
    d.end_utime = pass->end_utime;
  }

  // Skew between every two streams that observe the yaw rate (IMU gyro, wheel odometry, poses, scans), on threads
  // of its own while the rest is worked out here: it reads only the channels' motion once the pairs are chosen.
  const internal::PairPlan pair_plan = internal::plan_pairs(channels);
  std::jthread pairs_thread([&] { d.pairs = internal::stream_pairs(pair_plan, d.start_utime, d.end_utime, options); });

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
  // Asked for many stamps of one channel in a row: its domain found once per run of them.
  auto to_arrival = [&, last = std::string(), domain = -1](const std::string& channel, int64_t stamp) mutable {
    if (domain < 0 || channel != last) {
      last = channel;
      domain = domains.domain_of(channel);
    }
    return domains.to_arrival(domain, stamp);
  };
  for (auto& [name, s] : channels) {
    if (ignored(name)) continue;
    const int domain = domains.domain_of(name);
    std::function<int64_t(int64_t)> mapping;
    if (domain >= 0 && d.domains[static_cast<size_t>(domain)].mapped) {
      mapping = [&, domain](int64_t stamp) { return domains.to_arrival(domain, stamp); };
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
  pairs_thread.join();
  d.command_loops = exchanges->loops.finish(d.start_utime);
  for (const CommandLoop& l : d.command_loops) internal::judge_loop(l, d.channels);
  internal::judge_late_streams(d);
  d.timesync = exchanges->timesync.finish(d.start_utime, d.channels);
  for (auto& c : d.channels) internal::order_reasons(c);
  for (auto& [name, p] : exchanges->physics) d.physics.push_back(std::move(p));
  return d;
}

}  // namespace driftlab::analyzers
