#include "analyzers/flight_log_pair.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "analyzers/flight_log.h"
#include "analyzers/imu_clock_alignment.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "core/quantile.h"
#include "core/wall_clock.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

/// The bookkeeping channels every import writes: each message names the channel it describes, so both logs' go in.
bool bookkeeping(std::string_view channel) { return channel == "CHANNEL_SOURCES" || channel == "FOREIGN_SCHEMAS"; }

/// What one imported recording says of its clock: the angular rates of its IMU channel with the most messages
/// (header stamps), its time syncs (driftlab.timesync_status_t: MAVROS's /mavros/timesync_status), its span of
/// event times, and the channels it has.
struct ClockEvidence {
  std::string imu_channel;
  AngularRates rates;
  /// Per time-sync channel, each exchange's estimated offset and its stamp less the remote time [s].
  struct Exchange {
    double estimated_s, seen_s;
  };
  std::map<std::string, std::vector<Exchange>, std::less<>> timesyncs;
  int64_t first_utime = 0, last_utime = 0;
  std::set<std::string> channels;
};

Result<ClockEvidence> clock_evidence(const std::string& log) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  ClockEvidence ev;
  std::map<std::string, AngularRates, std::less<>> imus;
  Event e;
  imu_t m;
  timesync_status_t sync;
  bool any = false;
  while (reader->next(e)) {
    ev.first_utime = any ? std::min(ev.first_utime, e.utime) : e.utime;
    ev.last_utime = any ? std::max(ev.last_utime, e.utime) : e.utime;
    any = true;
    if (!bookkeeping(e.channel)) ev.channels.emplace(e.channel);
    // A flight log's ULOG_UTC (its GNSS time, in the same type) is not an exchange between two computers.
    if (e.channel != "ULOG_UTC" && lcmtypes::decode(e.data, sync) && std::isfinite(sync.estimated_offset_s)) {
      ev.timesyncs[std::string(e.channel)].push_back(
          {sync.estimated_offset_s, static_cast<double>(sync.header.utime - sync.remote_utime) * 1e-6});
      continue;
    }
    if (!lcmtypes::decode(e.data, m)) continue;
    const Eigen::Vector3d w(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z);
    if (!w.allFinite()) continue;
    auto& r = imus[std::string(e.channel)];
    r.stamps.push_back(static_cast<double>(m.header.utime) * 1e-6);
    r.rates.push_back(w);
  }
  for (auto& [name, r] : imus) {
    if (r.stamps.size() > ev.rates.stamps.size()) {
      ev.imu_channel = name;
      ev.rates = std::move(r);
    }
  }
  // Sorted by stamp, as the alignment wants (a bag's arrival order is not always its stamps').
  std::vector<size_t> order(ev.rates.stamps.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return ev.rates.stamps[a] < ev.rates.stamps[b]; });
  AngularRates sorted;
  for (const size_t i : order) {
    sorted.stamps.push_back(ev.rates.stamps[i]);
    sorted.rates.push_back(ev.rates.rates[i]);
  }
  ev.rates = std::move(sorted);
  return ev;
}

/// The flight controller's clock onto the bag's by the bag's time sync (MAVROS's /mavros/timesync_status, whose
/// `remote_timestamp_ns` is the flight controller's boot time, the clock the flight log is on): the offset MAVROS
/// estimated, the median over the exchanges, which is what MAVROS adds to the controller's stamps. MAVROS gives
/// it as local - remote; the sign is taken from the exchanges themselves (the status's stamp less the remote time
/// is the offset plus a one-way trip), so a writer with the other convention is read right too. Empty with a
/// problem when the bag has no time sync, or its offsets do not agree with its stamps within a second.
struct SyncOffset {
  double offset_s = 0;
  std::string line;  ///< how, for the alignment line
  std::string problem;
};

SyncOffset timesync_offset(const ClockEvidence& bag) {
  SyncOffset r;
  const std::vector<ClockEvidence::Exchange>* best = nullptr;
  std::string channel;
  for (const auto& [name, v] : bag.timesyncs) {
    if (best == nullptr || v.size() > best->size()) best = &v, channel = name;
  }
  if (best == nullptr) {
    r.problem = "no time sync (mavros_msgs/TimesyncStatus)";
    return r;
  }
  std::vector<double> estimated, seen;
  for (const auto& x : *best) {
    estimated.push_back(x.estimated_s);
    seen.push_back(x.seen_s);
  }
  const double est = quantile_in_place(estimated, 0.5), stamps = quantile_in_place(seen, 0.5);
  const double offset = std::abs(est - stamps) <= std::abs(-est - stamps) ? est : -est;
  char line[320];
  if (std::abs(offset - stamps) > 1.0) {
    std::snprintf(line, sizeof(line),
                  "%s: its estimated offset (%+.6f s) and its stamps against the remote times (%+.6f s) disagree by "
                  "more than a second",
                  channel.c_str(), est, stamps);
    r.problem = line;
    return r;
  }
  const auto [lo, hi] = std::minmax_element(estimated.begin(), estimated.end());
  std::snprintf(line, sizeof(line), "by the bag's time sync (%s, %zu exchanges, estimated offsets within %.1f ms)",
                channel.c_str(), best->size(), (*hi - *lo) * 1e3);
  r.offset_s = offset;
  r.line = line;
  return r;
}

/// The flight log's clock onto the bag's by GNSS time (analyzers/flight_log.h's flight_utc), when the bag's clock
/// is UTC: the flight's span in UTC must meet the bag's span of event times, give or take a minute.
SyncOffset gnss_offset(const std::string& ulog_log, const ClockEvidence& ulog, const ClockEvidence& bag) {
  SyncOffset r;
  const FlightUtc u = flight_utc(ulog_log, ulog.first_utime);
  if (!u.known) {
    r.problem = "no GNSS time in the flight log";
    return r;
  }
  constexpr int64_t kSlackUs = 60'000'000;
  const int64_t first = ulog.first_utime + u.boot_to_utc_us, last = ulog.last_utime + u.boot_to_utc_us;
  char line[400];
  if (last + kSlackUs < bag.first_utime || first - kSlackUs > bag.last_utime) {
    std::snprintf(line, sizeof(line),
                  "the flight was at %s (GNSS time) and the bag's events are at %s: the bag's clock is not UTC",
                  format_utime(first).c_str(), format_utime(bag.first_utime).c_str());
    r.problem = line;
    return r;
  }
  std::snprintf(line, sizeof(line),
                "by GNSS time (%s, %lld fixes agreeing within %.1f ms), the bag's clock taken as UTC",
                u.channel.c_str(), static_cast<long long>(u.fixes), u.spread_s * 1e3);
  r.offset_s = static_cast<double>(u.boot_to_utc_us) * 1e-6;
  r.line = line;
  return r;
}

std::string describe(const ClockAlignment& a, const std::string& ulog_imu, const std::string& bag_imu) {
  char line[512];
  std::snprintf(line, sizeof(line),
                "on the bag's clock by the IMUs' angular rates (%s against %s, correlation %.2f over %.1f s): "
                "offset %+.6f s",
                ulog_imu.c_str(), bag_imu.c_str(), a.confidence, a.overlap_s, a.offset_s);
  std::string s = line;
  if (a.drift_applied) {
    std::snprintf(line, sizeof(line), " at %.3f s of the flight log, drift %+.1f ppm (+/- %.1f, %d segments)", a.at_s,
                  a.drift * 1e6, a.drift_ci95 * 1e6, a.segments);
  } else if (a.drift_measured) {
    std::snprintf(line, sizeof(line), ", no drift measurable (%+.1f +/- %.1f ppm over %d segments)",
                  a.drift_measured_value * 1e6, a.drift_ci95 * 1e6, a.segments);
  } else {
    std::snprintf(line, sizeof(line), ", drift not measured (overlap under 120 s)");
  }
  return s + line;
}

/// Writes both logs into out by event time, the flight log's events and stamps through to_bag.
Status merge(const std::string& bag_log, const std::string& ulog_log, const std::string& out,
             const std::function<int64_t(int64_t)>& to_bag) {
  auto bag = LogReader::open(bag_log);
  if (!bag) return bag.error();
  auto ulog = LogReader::open(ulog_log);
  if (!ulog) return ulog.error();
  WriteOptions wo;
  wo.atomic = true;
  auto writer = LogWriter::create(out, wo);
  if (!writer) return writer.error();
  Event b, u;
  bool has_b = bag->next(b), has_u = ulog->next(u);
  std::vector<uint8_t> bytes;
  while (has_b || has_u) {
    const int64_t tu = has_u ? to_bag(u.utime) : 0;
    if (has_b && (!has_u || b.utime <= tu)) {
      if (Status s = writer->write(b.utime, b.channel, b.data); !s) return s;
      has_b = bag->next(b);
      continue;
    }
    bytes.assign(u.data.begin(), u.data.end());
    lcmtypes::map_stamps(bytes, u.utime, to_bag);  // false for messages without a header: nothing to map
    if (Status s = writer->write(tu, u.channel, bytes); !s) return s;
    has_u = ulog->next(u);
  }
  return writer->close();
}

}  // namespace

std::optional<FlightLogPair> flight_log_pair(const std::vector<std::string>& inputs) {
  if (inputs.size() < 2) return std::nullopt;
  FlightLogPair pair;
  for (const auto& in : inputs) {
    const formats::Format f = formats::detect_format(in).format;
    if (f == formats::Format::kUlog) {
      if (!pair.ulog.empty()) return std::nullopt;
      pair.ulog = in;
    } else if (formats::is_importable(f)) {
      pair.bag.push_back(in);
    } else {
      return std::nullopt;
    }
  }
  if (pair.ulog.empty() || pair.bag.empty()) return std::nullopt;
  return pair;
}

Result<PairImport> import_flight_log_pair(const FlightLogPair& pair, const std::string& out,
                                          const std::function<void(const std::string&)>& on_problem) {
  const std::string named =
      pair.bag[0] + (pair.bag.size() > 1 ? " (and " + std::to_string(pair.bag.size() - 1) + " more)" : std::string()) +
      " + " + pair.ulog;
  // Each recording imported on its own first, beside out (the same folder, so the same disk), removed after.
  const std::string tag = "." + std::to_string(::getpid()) + ".lcm";
  const std::string bag_log = out + ".bag" + tag, ulog_log = out + ".ulog" + tag;
  struct Remove {
    std::vector<std::string> files;
    ~Remove() {
      for (const auto& f : files) std::remove(f.c_str());
    }
  } cleanup{{bag_log, ulog_log}};
  auto bag_summary = formats::import_log(pair.bag, bag_log, on_problem);
  if (!bag_summary) return bag_summary.error();
  auto ulog_summary = formats::import_log(pair.ulog, ulog_log, on_problem);
  if (!ulog_summary) return ulog_summary.error();

  auto bag = clock_evidence(bag_log);
  if (!bag) return bag.error();
  auto ulog = clock_evidence(ulog_log);
  if (!ulog) return ulog.error();
  for (const auto& c : ulog->channels) {
    if (bag->channels.count(c)) {
      return Error(named + ": channel " + c + " is in both recordings; import them apart to rename one");
    }
  }
  // The bag's time sync first: it is the mapping MAVROS itself puts on the flight controller's stamps, so a late
  // stream of the bag stays late against the flight log. Then the IMUs, then GNSS time.
  std::string how;
  std::function<int64_t(int64_t)> to_bag;
  const SyncOffset sync = timesync_offset(*bag);
  std::vector<std::string> why;
  // A constant offset (the time sync's, GNSS time's).
  auto by_offset = [&](const SyncOffset& o) {
    const int64_t offset_us = std::llround(o.offset_s * 1e6);
    char line[64];
    std::snprintf(line, sizeof(line), ": offset %+.6f s", o.offset_s);
    how = "on the bag's clock " + o.line + line;
    to_bag = [offset_us](int64_t t) { return t + offset_us; };
  };
  if (sync.problem.empty()) {
    by_offset(sync);
  } else {
    why.push_back("by a time sync: the bag has " + sync.problem);
    ClockAlignment a;
    if (bag->imu_channel.empty()) {
      why.push_back("by the IMUs: the bag has no IMU (sensor_msgs/Imu, sensor_combined, vehicle_imu)");
    } else if (ulog->imu_channel.empty()) {
      why.push_back("by the IMUs: the flight log has no IMU (sensor_combined, vehicle_imu)");
    } else {
      a = align_imu_clocks(bag->rates, ulog->rates);
      if (!a.found)
        why.push_back("by the IMUs: " + ulog->imu_channel + " against " + bag->imu_channel + ": " + a.problem);
    }
    if (a.found) {
      const int64_t offset_us = std::llround(a.offset_s * 1e6), at_us = std::llround(a.at_s * 1e6);
      const double drift = a.drift;
      how = describe(a, ulog->imu_channel, bag->imu_channel);
      to_bag = [=](int64_t t) { return t + offset_us + std::llround(drift * static_cast<double>(t - at_us)); };
    } else {
      const SyncOffset gnss = gnss_offset(ulog_log, *ulog, *bag);
      if (!gnss.problem.empty()) {
        why.push_back("by GNSS time: " + gnss.problem);
        std::string all;
        for (const auto& w : why) all += (all.empty() ? "" : "; ") + w;
        return Error("cannot put " + pair.ulog + " on " + pair.bag[0] + "'s clock: " + all);
      }
      by_offset(gnss);
    }
  }
  if (Status s = merge(bag_log, ulog_log, out, to_bag); !s) return s.error();

  PairImport r;
  r.summary = std::move(*bag_summary);
  r.summary.format += " + " + ulog_summary->format;
  for (auto& t : ulog_summary->topics) r.summary.topics.push_back(std::move(t));
  r.summary.messages += ulog_summary->messages;
  r.summary.problems += ulog_summary->problems;
  r.alignment = pair.ulog + ": " + how;
  return r;
}

Result<formats::ImportSummary> import_recording(const std::vector<std::string>& inputs, const std::string& out,
                                                const std::function<void(const std::string&)>& on_problem,
                                                std::string* alignment) {
  const std::optional<FlightLogPair> pair = flight_log_pair(inputs);
  if (!pair) return formats::import_log(inputs, out, on_problem);
  auto both = import_flight_log_pair(*pair, out, on_problem);
  if (!both) return both.error();
  *alignment = std::move(both->alignment);
  return std::move(both->summary);
}

}  // namespace driftlab::analyzers
