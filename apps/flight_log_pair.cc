#include "apps/flight_log_pair.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "analyzers/imu_clock_alignment.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "driftlab/imu_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"

namespace driftlab::apps {
namespace {

/// The bookkeeping channels every import writes: each message names the channel it describes, so both logs' go in.
bool bookkeeping(std::string_view channel) { return channel == "CHANNEL_SOURCES" || channel == "FOREIGN_SCHEMAS"; }

/// The angular rates of the log's IMU channel with the most messages (header stamps), and the channels it has.
struct ImuChannel {
  std::string channel;
  analyzers::AngularRates rates;
};

Result<ImuChannel> busiest_imu(const std::string& log, std::set<std::string>* channels) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  std::map<std::string, analyzers::AngularRates, std::less<>> imus;
  Event e;
  imu_t m;
  while (reader->next(e)) {
    if (!bookkeeping(e.channel)) channels->emplace(e.channel);
    if (!lcmtypes::decode(e.data, m)) continue;
    const Eigen::Vector3d w(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z);
    if (!w.allFinite()) continue;
    auto& r = imus[std::string(e.channel)];
    r.stamps.push_back(static_cast<double>(m.header.utime) * 1e-6);
    r.rates.push_back(w);
  }
  ImuChannel best;
  for (auto& [name, r] : imus) {
    if (r.stamps.size() > best.rates.stamps.size()) best = ImuChannel{name, std::move(r)};
  }
  if (best.channel.empty()) return Error("no IMU (sensor_msgs/Imu, sensor_combined, vehicle_imu)");
  // Sorted by stamp, as the alignment wants (a bag's arrival order is not always its stamps').
  std::vector<size_t> order(best.rates.stamps.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return best.rates.stamps[a] < best.rates.stamps[b]; });
  analyzers::AngularRates sorted;
  for (const size_t i : order) {
    sorted.stamps.push_back(best.rates.stamps[i]);
    sorted.rates.push_back(best.rates.rates[i]);
  }
  best.rates = std::move(sorted);
  return best;
}

std::string describe(const analyzers::ClockAlignment& a, const std::string& ulog_imu, const std::string& bag_imu) {
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

  std::set<std::string> bag_channels, ulog_channels;
  auto bag_imu = busiest_imu(bag_log, &bag_channels);
  if (!bag_imu)
    return Error("cannot put " + pair.ulog + " on " + pair.bag[0] + "'s clock: the bag has " + bag_imu.error().message);
  auto ulog_imu = busiest_imu(ulog_log, &ulog_channels);
  if (!ulog_imu)
    return Error("cannot put " + pair.ulog + " on " + pair.bag[0] + "'s clock: the flight log has " +
                 ulog_imu.error().message);
  for (const auto& c : ulog_channels) {
    if (bag_channels.count(c)) {
      return Error(named + ": channel " + c + " is in both recordings; import them apart to rename one");
    }
  }
  const analyzers::ClockAlignment a = analyzers::align_imu_clocks(bag_imu->rates, ulog_imu->rates);
  if (!a.found) {
    return Error("cannot put " + pair.ulog + " on " + pair.bag[0] + "'s clock: " + ulog_imu->channel + " against " +
                 bag_imu->channel + ": " + a.problem);
  }
  const int64_t offset_us = std::llround(a.offset_s * 1e6), at_us = std::llround(a.at_s * 1e6);
  const double drift = a.drift;
  auto to_bag = [&](int64_t t) { return t + offset_us + std::llround(drift * static_cast<double>(t - at_us)); };
  if (Status s = merge(bag_log, ulog_log, out, to_bag); !s) return s.error();

  PairImport r;
  r.summary = std::move(*bag_summary);
  r.summary.format += " + " + ulog_summary->format;
  for (auto& t : ulog_summary->topics) r.summary.topics.push_back(std::move(t));
  r.summary.messages += ulog_summary->messages;
  r.summary.problems += ulog_summary->problems;
  r.alignment = pair.ulog + ": " + describe(a, ulog_imu->channel, bag_imu->channel);
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

}  // namespace driftlab::apps
