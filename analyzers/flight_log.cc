// The flight-log diagnosis (analyzers/flight_log.h): one pass over the log decodes each ULog topic through the
// format its channel's schema gives (FOREIGN_SCHEMAS, resolved by formats/ulog.h as the import resolved it), keeps
// the few series each check needs, then judges them.
#include "analyzers/flight_log.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>

#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/quantile.h"
#include "driftlab/channel_source_t.hpp"
#include "driftlab/dropout_t.hpp"
#include "driftlab/foreign_message_t.hpp"
#include "driftlab/foreign_schema_t.hpp"
#include "driftlab/timesync_status_t.hpp"
#include "formats/ulog.h"
#include "formats/ulog_messages.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

using formats::UlogLayout;
using formats::UlogType;

constexpr size_t kMaxEventsPerKind = 500;

/// PX4's IMU topics: the integrated IMU (sensor_combined, vehicle_imu) and the raw sensors.
bool is_imu_topic(std::string_view t) {
  return t == "sensor_combined" || t == "vehicle_imu" || t == "sensor_accel" || t == "sensor_gyro";
}

/// Topics a sensor driver (or the sensor hub right after it) publishes: their timestamp_sample is the sensor's.
/// The estimator's outputs carry the sample time of its delayed fusion horizon instead, by design.
bool is_sensor_topic(std::string_view t) {
  if (t.starts_with("sensor_")) {
    return t != "sensor_selection" && t != "sensor_preflight" && t != "sensor_correction" &&
           !t.starts_with("sensors_status");
  }
  for (std::string_view s : {"vehicle_imu", "vehicle_angular_velocity", "vehicle_acceleration", "vehicle_magnetometer",
                             "vehicle_air_data", "vehicle_gps_position", "vehicle_optical_flow", "distance_sensor",
                             "optical_flow", "airspeed", "differential_pressure"}) {
    if (t == s) return true;
  }
  return false;
}

/// The format a schema on FOREIGN_SCHEMAS describes (its definition: "name:type field;..." a line, its own first),
/// resolved as the import resolved it; null when it does not resolve.
std::shared_ptr<const UlogLayout> layout_of(const std::string& definition) {
  std::map<std::string, std::string, std::less<>> formats;
  std::string own;
  size_t at = 0;
  while (at < definition.size()) {
    size_t end = definition.find('\n', at);
    if (end == std::string::npos) end = definition.size();
    const std::string line = definition.substr(at, end - at);
    at = end + 1;
    const size_t colon = line.find(':');
    if (colon == std::string::npos || colon == 0) continue;
    const std::string name = line.substr(0, colon);
    if (own.empty()) own = name;
    formats.emplace(name, line);
  }
  if (own.empty()) return nullptr;
  auto l = formats::resolve_ulog_format(formats, own);
  if (!l) return nullptr;
  return std::make_shared<const UlogLayout>(std::move(*l));
}

/// One watched value of an estimator topic: a test ratio (element `index` of a float field), or a flag (a bool
/// field, or bit `bit` of an integer field).
struct Watch {
  const UlogLayout::Field* field = nullptr;
  uint32_t index = 0;
  int bit = -1;
  std::string name;
  std::string kind;                               // "test_ratio", "rejected", "timeout"
  std::vector<std::pair<int64_t, float>> values;  // (timestamp [us], ratio or 0/1)
};

/// The meaning of estimator_status' innovation_check_flags bits (PX4 1.11 and earlier: estimator_status.msg).
constexpr const char* kInnovationCheckBits[] = {"velocity",
                                                "horizontal position",
                                                "vertical position",
                                                "magnetometer x",
                                                "magnetometer y",
                                                "magnetometer z",
                                                "yaw",
                                                "airspeed",
                                                "synthetic sideslip",
                                                "height above ground",
                                                "optical flow x",
                                                "optical flow y"};
/// estimator_status' timeout_flags (velocity, position, height).
constexpr const char* kTimeoutBits[] = {"velocity", "position", "height"};

struct Topic {
  std::string channel;
  std::string topic;
  std::shared_ptr<const UlogLayout> layout;  // null for channels of driftlab's types (the typed mappings)
  bool watches_made = false;
  std::vector<Watch> watches;
  std::vector<int64_t> delays;  // timestamp - timestamp_sample [us]
  std::vector<int64_t> times;   // sample times of a sensor (timestamp_sample, else timestamp) [us]
  // Losses of IMU data (cumulative fields): first and latest value, and the sum of increases.
  struct Counter {
    std::string field;
    double last = std::numeric_limits<double>::quiet_NaN();
    double growth = 0;
  };
  std::vector<Counter> counters;
};

void make_watches(Topic& t) {
  t.watches_made = true;
  const UlogLayout& l = *t.layout;
  const std::string_view name = l.name;
  if (name == "estimator_innovation_test_ratios") {
    for (const auto& f : l.fields) {
      if (f.type != UlogType::kFloat) continue;
      const uint32_t n = std::max<uint32_t>(f.count, 1);
      for (uint32_t i = 0; i < n && i < 64; ++i) {
        t.watches.push_back({&f, i, -1, f.count ? f.name + "[" + std::to_string(i) + "]" : f.name, "test_ratio", {}});
      }
    }
  }
  if (name == "estimator_status") {
    for (const auto& f : l.fields) {
      if (f.type == UlogType::kFloat && f.count == 0 && f.name.ends_with("_test_ratio")) {
        t.watches.push_back({&f, 0, -1, f.name, "test_ratio", {}});
      }
    }
    if (const auto* f = l.find("innovation_check_flags");
        f && f->count == 0 && f->type != UlogType::kFloat && f->type != UlogType::kDouble) {
      for (int b = 0; b < static_cast<int>(std::size(kInnovationCheckBits)); ++b) {
        t.watches.push_back(
            {f, 0, b, std::string("innovation_check_flags: ") + kInnovationCheckBits[b], "rejected", {}});
      }
    }
    if (const auto* f = l.find("timeout_flags");
        f && f->count == 0 && f->type != UlogType::kFloat && f->type != UlogType::kDouble) {
      for (int b = 0; b < static_cast<int>(std::size(kTimeoutBits)); ++b) {
        t.watches.push_back({f, 0, b, std::string("timeout_flags: ") + kTimeoutBits[b], "timeout", {}});
      }
    }
    if (const auto* f = l.find("time_slip"); f && f->type == UlogType::kFloat && f->count == 0) {
      t.counters.push_back({"time_slip"});
    }
  }
  if (name == "estimator_status_flags" || name == "estimator_event_flags") {
    for (const auto& f : l.fields) {
      if (f.type != UlogType::kBool || f.count != 0) continue;
      if (name == "estimator_status_flags" && f.name.starts_with("reject_")) {
        t.watches.push_back({&f, 0, -1, f.name, "rejected", {}});
      } else if (f.name.find("timeout") != std::string::npos || f.name.find("timout") != std::string::npos) {
        t.watches.push_back({&f, 0, -1, f.name, "timeout", {}});  // PX4 spells one "gps_fusion_timout"
      }
    }
  }
  if (name == "vehicle_imu_status") {
    for (const char* c : {"accel_error_count", "gyro_error_count"}) {
      if (const auto* f = l.find(c); f && f->count == 0 && f->type == UlogType::kUint32) t.counters.push_back({c});
    }
  }
}

/// A watched value of one message: NaN when it cannot be read (a missing field, a message cut short).
double watched(const UlogLayout& l, const Watch& w, std::span<const uint8_t> p) {
  const double v = l.number(p, w.field->name, w.index);
  if (w.bit < 0 || !std::isfinite(v)) return v;
  if (v < 0 || v >= 18446744073709551616.0) return std::numeric_limits<double>::quiet_NaN();
  return (static_cast<uint64_t>(v) >> w.bit) & 1u ? 1.0 : 0.0;
}

void read_message(Topic& t, std::span<const uint8_t> p, int64_t event_utime) {
  const UlogLayout& l = *t.layout;
  const auto ts = l.u64(p, "timestamp");
  const auto sample = l.u64(p, "timestamp_sample");
  const int64_t now = ts ? formats::ulog_utime(*ts) : event_utime;
  if (ts && sample) {
    const double d = static_cast<double>(*ts) - static_cast<double>(*sample);
    if (std::abs(d) < 9e15) t.delays.push_back(static_cast<int64_t>(d));
  }
  if (is_imu_topic(t.topic) || is_sensor_topic(t.topic)) t.times.push_back(sample ? formats::ulog_utime(*sample) : now);
  if (!t.watches_made) make_watches(t);
  for (Watch& w : t.watches) {
    const double v = watched(l, w, p);
    if (std::isfinite(v)) w.values.emplace_back(now, static_cast<float>(std::clamp(v, -3.4e38, 3.4e38)));
  }
  for (Topic::Counter& c : t.counters) {
    const double v = l.number(p, c.field);
    if (!std::isfinite(v)) continue;
    if (std::isfinite(c.last) && v > c.last) c.growth += v - c.last;
    c.last = v;
  }
}

double median_interval_us(const std::vector<int64_t>& times) {
  std::vector<double> d;
  for (size_t i = 1; i < times.size(); ++i) {
    if (times[i] > times[i - 1]) d.push_back(static_cast<double>(times[i]) - static_cast<double>(times[i - 1]));
  }
  return d.empty() ? 0.0 : quantile_in_place(d, 0.5);
}

std::string fmt(const char* f, auto... args) {
  char buf[640];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

}  // namespace

Result<FlightLogDiagnosis> diagnose_flight_log(const std::string& log, const FlightLogThresholds& th) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  FlightLogDiagnosis out;
  const int64_t foreign_hash = driftlab::foreign_message_t::getHash();
  const int64_t schema_hash = driftlab::foreign_schema_t::getHash();
  const int64_t source_hash = driftlab::channel_source_t::getHash();
  const int64_t dropout_hash = driftlab::dropout_t::getHash();
  std::map<std::string, Topic, std::less<>> topics;
  std::map<std::string, std::shared_ptr<const UlogLayout>, std::less<>> schemas;  // by channel
  std::map<std::string, std::string, std::less<>> source_types;                   // CHANNEL_SOURCES
  std::vector<std::pair<int64_t, int64_t>> dropouts;                              // (utime, duration) [us]
  bool first = true;
  Event e;
  foreign_message_t f;
  while (reader->next(e)) {
    if (first || e.utime < out.start_utime) out.start_utime = e.utime;
    first = false;
    const int64_t fp = logfmt::fingerprint(e.data);
    if (e.channel.starts_with("ULOG_")) out.present = true;
    if (fp == dropout_hash && e.channel == "ULOG_DROPOUTS") {
      dropout_t m;
      if (lcmtypes::decode(e.data, m) && m.duration_us >= 0) dropouts.emplace_back(m.header.utime, m.duration_us);
      continue;
    }
    if (fp == schema_hash) {
      foreign_schema_t s;
      if (lcmtypes::decode(e.data, s) && s.encoding == "ulog") {
        out.present = true;
        schemas[s.channel] = layout_of(s.definition);
      }
      continue;
    }
    if (fp == source_hash) {
      channel_source_t s;
      if (lcmtypes::decode(e.data, s)) source_types[s.channel] = s.source_type;
      continue;
    }
    if (fp == foreign_hash) {
      if (!lcmtypes::decode(e.data, f) || f.encoding != "ulog") continue;
      out.present = true;
      auto it = topics.find(e.channel);
      if (it == topics.end()) {
        Topic t;
        t.channel = std::string(e.channel);
        if (auto s = schemas.find(e.channel); s != schemas.end()) t.layout = s->second;
        t.topic = t.layout ? t.layout->name : f.type;
        it = topics.emplace(t.channel, std::move(t)).first;
      }
      Topic& t = it->second;
      // A channel whose schema is missing, did not resolve, or is another topic's is left out.
      if (!t.layout || t.layout->name != f.type) continue;
      read_message(t, f.data, e.utime);
      continue;
    }
    // A PX4 topic imported as one of driftlab's types (formats/ulog_messages.h): its header stamp is
    // timestamp_sample where the topic has one, the event's time its timestamp.
    auto it = topics.find(e.channel);
    if (it == topics.end()) {
      Topic t;
      t.channel = std::string(e.channel);
      const auto s = source_types.find(e.channel);
      t.topic = s != source_types.end() ? s->second : t.channel.substr(0, t.channel.find('/'));
      if (formats::driftlab_type_for_ulog(t.topic) == nullptr) t.topic.clear();  // not a ULog topic: ignored
      it = topics.emplace(t.channel, std::move(t)).first;
    }
    Topic& t = it->second;
    if (t.topic.empty() || t.layout) continue;
    const auto stamp = lcmtypes::header_stamp(e.data, e.utime);
    if (!stamp) continue;
    const double d = static_cast<double>(e.utime) - static_cast<double>(*stamp);
    if (std::abs(d) < 9e15) t.delays.push_back(static_cast<int64_t>(d));  // a hostile stamp cannot overflow it
    if (is_imu_topic(t.topic) || is_sensor_topic(t.topic)) t.times.push_back(*stamp);
  }
  if (!out.present) return FlightLogDiagnosis{};
  const int64_t start = out.start_utime;
  // In doubles: hostile times may lie anywhere in int64_t.
  auto since = [&](int64_t us) { return (static_cast<double>(us) - static_cast<double>(start)) * 1e-6; };

  // ---- the logger's dropouts ----
  for (const auto& [t, d] : dropouts) {
    out.dropouts.push_back({since(t), static_cast<double>(d) * 1e-6});
    out.dropout_total_s += static_cast<double>(d) * 1e-6;
    out.dropout_max_s = std::max(out.dropout_max_s, static_cast<double>(d) * 1e-6);
    if (out.timeline.size() < kMaxEventsPerKind) {
      out.timeline.push_back({"dropout", "logger", since(t), since(t) + static_cast<double>(d) * 1e-6});
    }
  }
  out.dropout_count = static_cast<int64_t>(dropouts.size());
  if (out.dropout_count >= th.dropouts && out.dropout_count > 0) {
    double worst_at = 0;
    for (const auto& d : out.dropouts) {
      if (d.duration_s == out.dropout_max_s) {
        worst_at = d.at_s;
        break;
      }
    }
    out.problems.push_back(
        fmt("the logger's buffer overflowed: %lld dropout%s, %.0f ms of the flight missing from every topic (the "
            "longest %.0f ms, at %.1f s); log fewer topics or at lower rates, or use a faster SD card",
            static_cast<long long>(out.dropout_count), out.dropout_count == 1 ? "" : "s", out.dropout_total_s * 1e3,
            out.dropout_max_s * 1e3, worst_at));
  }
  // Whether a logger dropout lies within [a, b] (us): a gap there is the logger's loss, not the sensor's.
  auto at_dropout = [&](int64_t a, int64_t b) {
    return std::any_of(dropouts.begin(), dropouts.end(), [&](const auto& d) { return d.first >= a && d.first <= b; });
  };

  size_t gap_events = 0, rejection_events = 0, timeout_events = 0;
  bool any_reject_flag = false;  // estimator_status_flags' reject_* (newer PX4) say what innovation_check_flags said
  for (const auto& [name, t] : topics) {
    for (const auto& w : t.watches)
      if (w.kind == "rejected" && w.bit < 0) any_reject_flag = true;
  }
  // ---- sample to publication; the estimator's fusion horizon ----
  // EKF2 fuses measurements at a delayed horizon (as far back as its largest EKF2_*_DELAY) and stamps its outputs
  // with that horizon's sample time: their timestamp - timestamp_sample is the horizon. A sensor's sample published
  // later than it reaches the estimator after it has fused past the sample's time.
  double horizon_s = std::numeric_limits<double>::quiet_NaN();
  for (auto& [name, t] : topics) {
    if (t.topic.empty()) continue;
    const bool typed = !t.layout;
    const bool delays_seen = std::any_of(t.delays.begin(), t.delays.end(), [](int64_t d) { return d != 0; });
    if (t.delays.empty() || (typed && !delays_seen)) continue;
    SampleDelay s;
    s.channel = t.channel;
    s.topic = t.topic;
    s.sensor = is_sensor_topic(t.topic);
    s.count = static_cast<int64_t>(t.delays.size());
    std::vector<double> d;
    d.reserve(t.delays.size());
    for (const int64_t x : t.delays) {
      d.push_back(static_cast<double>(x) * 1e-6);
      if (x < 0) ++s.negative;
    }
    s.max_s = *std::max_element(d.begin(), d.end());
    s.p50_s = quantile_in_place(d, 0.5);
    s.p99_s = quantile_in_place(d, 0.99);
    if ((t.topic == "estimator_status" || t.topic == "estimator_innovations") && s.count >= 5 &&
        !(s.p50_s <= horizon_s)) {
      horizon_s = s.p50_s;
      out.horizon_channel = t.channel;
    }
    out.sample_delays.push_back(std::move(s));
  }
  out.horizon_s = std::isfinite(horizon_s) ? horizon_s : 0;
  for (const auto& s : out.sample_delays) {
    if (!s.sensor) continue;
    const bool imu =
        is_imu_topic(s.topic) || s.topic == "vehicle_angular_velocity" || s.topic == "vehicle_acceleration";
    const double limit = imu                                         ? th.imu_delay_p99_s
                         : std::isfinite(horizon_s) && horizon_s > 0 ? horizon_s
                                                                     : th.sample_delay_p99_s;
    if (!(s.p99_s > limit)) continue;
    out.problems.push_back(fmt(
        "%s publishes its samples late: %.1f ms after sampling (p99; p50 %.1f ms, max %.1f ms), over the %.0f ms %s: "
        "its driver or work queue runs behind%s",
        s.channel.c_str(), s.p99_s * 1e3, s.p50_s * 1e3, s.max_s * 1e3, limit * 1e3,
        imu                                         ? "an IMU sample may take (five 250 Hz cycles)"
        : std::isfinite(horizon_s) && horizon_s > 0 ? "of the estimator's fusion horizon"
                                                    : "EKF2's default fusion horizon allows",
        imu ? ", and everything fed by the IMU lags by as much"
            : ", and the estimator drops what comes after it has fused past"));
  }

  // ---- sensor intervals: the IMU's regularity, every sensor's gaps ----
  struct SensorGaps {
    const Topic* topic = nullptr;
    ImuIntervals iv;
    std::vector<std::pair<int64_t, int64_t>> gaps;  // [us]
  };
  std::vector<SensorGaps> sensors;
  for (auto& [name, t] : topics) {
    if (t.topic.empty() || t.times.size() < 3) continue;
    const double nominal = median_interval_us(t.times);
    if (nominal <= 0) continue;
    SensorGaps g;
    g.topic = &t;
    ImuIntervals& iv = g.iv;
    iv.channel = t.channel;
    iv.topic = t.topic;
    int64_t n1 = 0, n2 = 0, n0 = 0, other = 0;
    for (size_t i = 1; i < t.times.size(); ++i) {
      const double d = static_cast<double>(t.times[i]) - static_cast<double>(t.times[i - 1]);
      const double r = d / nominal;
      if (r < 0.25)
        ++n0;
      else if (r >= 0.75 && r <= 1.25)
        ++n1;
      else if (r >= 1.75 && r <= 2.25)
        ++n2;
      else
        ++other;
      if (d * 1e-6 > iv.longest_s) {
        iv.longest_s = d * 1e-6;
        iv.longest_at_s = since(t.times[i - 1]);
      }
      if (r >= th.gap_periods) g.gaps.emplace_back(t.times[i - 1], t.times[i]);
    }
    const double n = static_cast<double>(t.times.size() - 1);
    iv.intervals = static_cast<int64_t>(t.times.size() - 1);
    iv.nominal_s = nominal * 1e-6;
    iv.share_1x = static_cast<double>(n1) / n;
    iv.share_2x = static_cast<double>(n2) / n;
    iv.share_0 = static_cast<double>(n0) / n;
    iv.share_other = static_cast<double>(other) / n;
    iv.gaps = static_cast<int64_t>(g.gaps.size());
    sensors.push_back(std::move(g));
  }
  // Fewer than 20 intervals say nothing of a period (a topic the logger wrote once a second, briefly).
  auto judged = [](const SensorGaps& g) { return g.iv.intervals >= 20; };
  const auto n_judged = std::count_if(sensors.begin(), sensors.end(), judged);
  // A gap most sensors share is the log's, not a sensor's: the logger (or the whole flight controller) stalled.
  auto shared = [&](const SensorGaps& self, int64_t a, int64_t b) {
    int64_t others = 0;
    for (const auto& g : sensors) {
      if (&g == &self || !judged(g)) continue;
      if (std::any_of(g.gaps.begin(), g.gaps.end(), [&](const auto& x) { return x.first < b && x.second > a; })) {
        ++others;
      }
    }
    return others >= 2 && 2 * others >= n_judged - 1;
  };
  std::vector<std::pair<int64_t, int64_t>> stalls;
  for (const auto& g : sensors) {
    const Topic& t = *g.topic;
    int64_t own = 0;
    double own_longest = 0, own_at = 0;
    for (const auto& [a, b] : g.gaps) {
      const bool logger = at_dropout(a, b);
      const bool stall = !logger && judged(g) && shared(g, a, b);
      if (stall) stalls.emplace_back(a, b);
      if (!logger && !stall && judged(g)) {
        ++own;
        if ((static_cast<double>(b) - static_cast<double>(a)) * 1e-6 > own_longest) {
          own_longest = (static_cast<double>(b) - static_cast<double>(a)) * 1e-6;
          own_at = since(a);
        }
      }
      if (!stall && gap_events++ < kMaxEventsPerKind) {  // a stall goes on the timeline once, below
        out.timeline.push_back(
            {"sensor_gap", t.channel + (logger ? " (at a logger dropout)" : ""), since(a), since(b)});
      }
    }
    const ImuIntervals& iv = g.iv;
    const bool imu = is_imu_topic(t.topic);
    if (imu && judged(g) && iv.share_2x + iv.share_0 >= th.imu_skip_share) {
      const bool catches_up = iv.share_0 >= th.imu_skip_share / 2;
      out.problems.push_back(
          fmt("%s's scheduler skips cycles: %.0f%% of its intervals are two periods (%.1f ms) and %.0f%% about none, "
              "instead of one (%.1f ms; %.0f%% are): %s",
              t.channel.c_str(), iv.share_2x * 100, 2 * iv.nominal_s * 1e3, iv.share_0 * 100, iv.nominal_s * 1e3,
              iv.share_1x * 100,
              catches_up ? "a loop that runs late and catches up by publishing two samples at once; the estimator "
                           "integrates them as one step"
                         : "a loop that runs late and drops the sample it missed; the estimator integrates over twice "
                           "the period there"));
    }
    if (own > 0) {
      out.problems.push_back(
          fmt("%s stopped publishing %lld time%s for %.1f periods or more, with no logger dropout%s "
              "(the longest %.0f ms at %.1f s, against a %.1f ms period): the sensor or its driver",
              t.channel.c_str(), static_cast<long long>(own), own == 1 ? "" : "s", th.gap_periods,
              n_judged > 1 ? " and the other sensors going on" : "", own_longest * 1e3, own_at, iv.nominal_s * 1e3));
    }
    if (imu) out.imu.push_back(iv);
  }
  if (!stalls.empty()) {
    std::sort(stalls.begin(), stalls.end());
    std::vector<std::pair<int64_t, int64_t>> merged;
    for (const auto& s : stalls) {
      if (!merged.empty() && s.first <= merged.back().second) {
        merged.back().second = std::max(merged.back().second, s.second);
      } else {
        merged.push_back(s);
      }
    }
    double longest = 0, at = 0;
    for (const auto& [a, b] : merged) {
      if (gap_events++ < kMaxEventsPerKind) {
        out.timeline.push_back({"sensor_gap", "every sensor at once (a stall)", since(a), since(b)});
      }
      if ((static_cast<double>(b) - static_cast<double>(a)) * 1e-6 > longest) {
        longest = (static_cast<double>(b) - static_cast<double>(a)) * 1e-6;
        at = since(a);
      }
    }
    out.problems.push_back(
        fmt("the log holds nothing from most sensors %lld time%s (the longest %.0f ms, at %.1f s) "
            "with no dropout recorded: the logger, or the whole flight controller, stalled; no "
            "single sensor is at fault",
            static_cast<long long>(merged.size()), merged.size() == 1 ? "" : "s", longest * 1e3, at));
  }

  for (auto& entry : topics) {
    Topic& t = entry.second;  // not a structured binding: the lambdas below capture it
    if (t.topic.empty()) continue;
    // ---- the estimator ----
    for (Watch& w : t.watches) {
      if (w.kind == "rejected" && w.bit >= 0 && any_reject_flag) continue;
      if (w.values.empty()) continue;
      EstimatorCheck s;
      s.channel = t.channel;
      s.field = w.name;
      s.kind = w.kind;
      s.samples = static_cast<int64_t>(w.values.size());
      std::vector<int64_t> times;
      times.reserve(w.values.size());
      for (const auto& v : w.values) times.push_back(v.first);
      const double cap_us = 2 * median_interval_us(times);
      auto over = [&](float v) { return w.kind == "test_ratio" ? v > 1.0f : v != 0.0f; };
      bool open = false;
      double span_start = 0, span_end = 0;
      auto close = [&] {
        if (!open) return;
        open = false;
        size_t& count = w.kind == "timeout" ? timeout_events : rejection_events;
        if (count++ < kMaxEventsPerKind) {
          out.timeline.push_back(
              {w.kind == "timeout" ? "timeout" : "rejection", t.channel + " " + w.name, span_start, span_end});
        }
      };
      for (size_t i = 0; i < w.values.size(); ++i) {
        const auto& [time, v] = w.values[i];
        s.max = std::max(s.max, static_cast<double>(v));
        if (!over(v)) {
          close();
          continue;
        }
        ++s.over;
        double step = 0;
        if (i + 1 < w.values.size() && w.values[i + 1].first > time) {
          step = std::min(static_cast<double>(w.values[i + 1].first - time), cap_us);
        }
        s.time_over_s += step * 1e-6;
        if (s.first_s < 0) s.first_s = since(time);
        if (!open) {
          open = true;
          span_start = since(time);
        }
        span_end = since(time) + step * 1e-6;
      }
      close();
      if (s.over == 0 && s.kind != "test_ratio") continue;
      if (s.kind == "timeout" && s.over >= th.timeouts) {
        out.problems.push_back(
            fmt("the estimator timed out on %s (%s, %s): set in %lld of %lld samples, first at "
                "%.1f s: it stopped receiving that measurement and flew on its prediction",
                w.name.c_str(), t.channel.c_str(), t.topic.c_str(), static_cast<long long>(s.over),
                static_cast<long long>(s.samples), s.first_s));
      } else if (s.kind != "timeout" && s.over > 0 && s.time_over_s >= th.rejected_s) {
        out.problems.push_back(
            fmt("the estimator rejected %s (%s%s) for %.1f s in all (%lld of %lld samples, first at %.1f s%s): that "
                "measurement disagreed with the prediction (a sensor glitch, a bad calibration, or its timestamps "
                "late against the IMU's)",
                w.name.c_str(), t.channel.c_str(), s.kind == "test_ratio" ? ", test ratio over 1" : ", flag set",
                s.time_over_s, static_cast<long long>(s.over), static_cast<long long>(s.samples), s.first_s,
                s.kind == "test_ratio" ? fmt(", max %.2f", s.max).c_str() : ""));
      }
      out.estimator.push_back(std::move(s));
    }
    for (const auto& c : t.counters) {
      out.imu_loss.push_back({t.channel, c.field, c.growth});
      if (c.field == "time_slip" && c.growth >= th.time_slip_s) {
        out.problems.push_back(
            fmt("the estimator dropped IMU data: its inertial prediction fell %.0f ms behind the "
                "IMU (%s time_slip): its loop overran the IMU's rate",
                c.growth * 1e3, t.channel.c_str()));
      } else if (c.field != "time_slip" && c.growth >= 1) {
        out.problems.push_back(
            fmt("the IMU driver reported %.0f errors (%s %s): samples it lost or rejected before "
                "the estimator",
                c.growth, t.channel.c_str(), c.field.c_str()));
      }
    }
  }
  std::stable_sort(out.timeline.begin(), out.timeline.end(),
                   [](const FlightEvent& a, const FlightEvent& b) { return a.start_s < b.start_s; });
  out.utc = flight_utc(log, out.start_utime);
  return out;
}

FlightUtc flight_utc(const std::string& log, int64_t start_utime) {
  FlightUtc out;
  const std::string info = "ULOG_INFO";  // its information fields: stamped with the ULog header's start
  auto reader = LogReader::open(log, {.channels = std::string(formats::kUlogUtcChannel) + "|" + info});
  if (!reader) return out;
  std::vector<double> offsets;  // [us]: exact in a double up to 2^53 us (285 years)
  std::optional<int64_t> header_start;
  Event e;
  timesync_status_t m;
  while (reader->next(e)) {
    if (e.channel == info) {
      header_start = std::min(header_start.value_or(e.utime), e.utime);
      continue;
    }
    if (e.channel != formats::kUlogUtcChannel || !lcmtypes::decode(e.data, m)) continue;
    const double offset = static_cast<double>(m.remote_utime) - static_cast<double>(m.header.utime);
    if (!(std::abs(offset) < 9e15)) continue;  // hostile values: outside what an int64_t sum can hold
    if (offsets.empty()) out.channel = m.header.frame_id;
    offsets.push_back(offset);
  }
  out.start_utime = header_start.value_or(start_utime);
  if (offsets.empty()) return out;
  out.known = true;
  out.fixes = static_cast<int64_t>(offsets.size());
  const auto [lo, hi] = std::minmax_element(offsets.begin(), offsets.end());
  out.spread_s = (*hi - *lo) * 1e-6;
  out.boot_to_utc_us = std::llround(quantile_in_place(offsets, 0.5));
  // A hostile start may lie anywhere in int64_t: held at its ends.
  if (__builtin_add_overflow(out.start_utime, out.boot_to_utc_us, &out.start_utc_us)) {
    out.start_utc_us = out.start_utime < 0 ? INT64_MIN : INT64_MAX;
  }
  return out;
}

}  // namespace driftlab::analyzers
