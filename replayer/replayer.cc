#include "replayer/replayer.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <queue>
#include <regex>
#include <set>
#include <sstream>
#include <unordered_map>

#include "core/config.h"
#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/time.h"
#include "driftlab/fault_manifest_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"

namespace driftlab::replay {

const config::Table<RestampFile>& restamp_file_table() {
  using C = ClockCorrection;
  static const auto correction =
      config::Table<C>()
          .number("offset_s", &C::offset_s, config::between(-86400, 86400), "s",
                  "the stream's clock was ahead of the log's by this much ...")
          .number("drift_ppm", &C::drift_ppm, config::between(-1e5, 1e5), "ppm",
                  "... plus this much per second since reference_utime; the correction subtracts both")
          .integer("reference_utime", &C::reference_utime, config::between(0, 9e18), "us",
                   "when the drift is zero; 0: the first event of the replay");
  static const auto t = config::Table<RestampFile>()
                            .map("channels", &RestampFile::channels, "CHANNEL", correction,
                                 "the clock correction of each channel, as named in the input logs")
                            .required();
  return t;
}

Result<Restamp> load_restamp(const std::string& path) {
  auto root = config::load_yaml(path, "restamp file");
  if (!root) return root.error();
  auto file = restamp_file_table().parse(config::Value(*root, path));
  if (!file) return file.error();
  return std::move(file->channels);
}

namespace {

/// An input on its way to the modules.
struct Item {
  Time time;             ///< delivery time
  int64_t order = 0;     ///< creation order: ties keep it
  const std::string* channel = nullptr;  ///< the delivered (remapped) name, interned
  std::vector<uint8_t> owned;            ///< the bytes when changed (restamped, injected)
  std::span<const uint8_t> view;         ///< else the bytes in the mapped log
  std::span<const uint8_t> data() const { return owned.empty() ? view : std::span<const uint8_t>(owned); }
};
struct Later {
  bool operator()(const Item& a, const Item& b) const {
    return a.time != b.time ? a.time > b.time : a.order > b.order;
  }
};
using ItemHeap = std::priority_queue<Item, std::vector<Item>, Later>;

/// The logs merged by log time, with -c, --start and --end applied.
class Merger {
 public:
  static Result<Merger> open(const ReplayOptions& o, const std::function<void(const Problem&)>& on_problem) {
    Merger m;
    for (const auto& path : o.logs) {
      ReadOptions ro;
      ro.channels = o.channels;
      ro.on_problem = on_problem;
      auto r = LogReader::open(path, ro);
      if (!r) return r.error();
      m.sources_.push_back({std::move(*r), {}, false});
    }
    Time first = Time::max();
    for (auto& s : m.sources_) {
      s.has = s.reader.next(s.event);
      if (s.has) first = std::min(first, Time::from_us(s.event.utime));
    }
    if (first == Time::max()) return m;  // nothing to replay
    m.base_ = first;
    if (o.start_s > 0) {
      const Time from = first.plus_seconds_saturated(o.start_s);
      for (auto& s : m.sources_) {
        if (s.has && Time::from_us(s.event.utime) >= from) continue;
        if (Status st = s.reader.seek(from.us()); !st) return st.error();
        s.has = s.reader.next(s.event);
      }
    }
    if (std::isfinite(o.end_s)) m.end_ = first.plus_seconds_saturated(o.end_s);
    return m;
  }

  /// The time of the next event, or nullopt at the end.
  std::optional<Time> peek() {
    const Source* s = best();
    if (s == nullptr) return std::nullopt;
    return Time::from_us(s->event.utime);
  }
  bool next(Event& out) {
    Source* s = best();
    if (s == nullptr) return false;
    out = s->event;
    s->has = s->reader.next(s->event);
    return true;
  }
  Time base() const { return base_; }
  /// Bytes of the logs read so far, and their total.
  std::pair<uint64_t, uint64_t> bytes() const {
    uint64_t done = 0, total = 0;
    for (const auto& s : sources_) {
      done += s.has ? s.reader.position() : s.reader.size_bytes();
      total += s.reader.size_bytes();
    }
    return {done, total};
  }
  uint64_t problems() const {
    uint64_t n = 0;
    for (const auto& s : sources_) n += s.reader.problems();
    return n;
  }

 private:
  struct Source {
    LogReader reader;
    Event event;
    bool has;
  };
  Source* best() {
    Source* b = nullptr;
    for (auto& s : sources_) {
      if (s.has && Time::from_us(s.event.utime) > end_) s.has = false;
      if (s.has && (b == nullptr || s.event.utime < b->event.utime)) b = &s;
    }
    return b;
  }
  Merger() = default;
  std::vector<Source> sources_;
  Time base_;
  Time end_ = Time::max();
};

}  // namespace

struct Replayer::Prepared {
  std::optional<Merger> merger;
};

namespace {

runtime::HostOptions host_options(const ReplayOptions& o) {
  return {.clock = runtime::HostClock::kVirtual,
          .loopback = true,
          .out = o.out,
          .timing = o.timing,
          .stats_period_s = o.stats_period_s,
          .stats_channel = o.stats_channel};
}

/// Hands one input to the modules at its time: the timer ticks before it, the statistics, the input itself (to the
/// output log when it keeps inputs, and to the sink), and everything the modules publish in turn.
Status deliver(runtime::ModuleHost& host, const ReplayOptions& o, ReplayReport& report, const Item& item) {
  if (Status s = host.advance(item.time); !s) return s;
  if (report.dispatched == 0) report.start_utime = host.now().us();
  report.end_utime = host.now().us();
  ++report.dispatched;
  ++report.channels[*item.channel];
  if (Status s = host.record(*item.channel, item.data(), o.write_inputs, true); !s) return s;
  return host.deliver(*item.channel, item.data());
}

/// The manifest of the injected faults, encoded.
std::vector<uint8_t> encode_manifest(const ReplayOptions& o, int64_t utime, const std::vector<fault_t>& injected) {
  driftlab::fault_manifest_t m;
  m.header.utime = utime;
  m.header.seq = 0;
  m.seed = static_cast<int64_t>(o.inject ? o.inject->seed : 0);
  m.faults = injected;
  m.nfaults = static_cast<int32_t>(m.faults.size());
  std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace

Result<std::pair<std::string, std::string>> parse_remap(const std::string& item) {
  const auto eq = item.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == item.size()) {
    return Error{"--remap " + item + ": expected FROM=TO (channel names)"};
  }
  return std::pair{item.substr(0, eq), item.substr(eq + 1)};
}

Status refuse_absent_channels(const std::string& what, const std::vector<std::string>& channels,
                              const std::vector<std::string>& logs) {
  if (channels.empty()) return {};
  std::set<std::string> present;
  for (const auto& log : logs) {
    auto index = LogIndex::load_or_build(log);
    if (!index) return index.error();
    for (const auto& c : index->summary().channels) present.insert(c.name);
  }
  for (const auto& channel : channels) {
    if (present.count(channel) != 0) continue;
    std::string known;
    int listed = 0;
    for (const auto& p : present) {
      if (listed++ == 8) {
        known += ", ...";
        break;
      }
      known += (known.empty() ? "" : ", ") + p;
    }
    return Error{what + ": no channel '" + channel + "' in the logs given (they have: " + known + ")"};
  }
  return {};
}

const char* to_string(Order order) { return order == Order::kStamp ? "stamp" : "received"; }

InputChannels delivered_channels(const ReplayOptions& o) {
  // The first rule naming an input applies, as in run().
  auto delivered_as = [&o](const std::string& input) {
    for (const auto& [from, to] : o.remap) {
      if (input == from) return to;
    }
    return input;
  };
  std::optional<std::regex> filter;
  try {
    if (!o.channels.empty()) filter.emplace(o.channels);
  } catch (const std::regex_error&) {
    return {};  // open() reports the bad regex
  }
  std::map<std::string, InputChannel> by_name;
  for (const auto& log : o.logs) {
    auto index = LogIndex::load_or_build(log);
    if (!index) continue;  // open() reports it
    for (const auto& c : index->summary().channels) {
      if (filter && !std::regex_match(c.name, *filter)) continue;
      InputChannel& in = by_name[delivered_as(c.name)];
      if (in.count == 0) {
        const char* type = lcmtypes::type_name(c.fingerprint);
        in.type = type != nullptr ? type : "";
      }
      in.count += c.count;
    }
  }
  InputChannels out;
  for (auto& [name, in] : by_name) {
    in.name = name;
    out.push_back(std::move(in));
  }
  return out;
}

Replayer::Replayer(ReplayOptions options)
    : options_(std::move(options)), host_(std::make_unique<runtime::ModuleHost>(host_options(options_))) {}
Replayer::~Replayer() = default;
void Replayer::add_module(std::unique_ptr<Module> module) { host_->add_module(std::move(module)); }

Status Replayer::open() {
  if (prepared_) return {};
  const ReplayOptions& o = options_;
  for (const auto& [from, to] : o.remap) {
    if (from.empty() || to.empty()) return Error{"--remap " + from + "=" + to + ": both names must be non-empty"};
  }
  auto merger = Merger::open(o, nullptr);
  if (!merger) return merger.error();
  if (Status s = host_->start(); !s) return s;
  prepared_ = std::make_unique<Prepared>();
  prepared_->merger.emplace(std::move(*merger));
  return {};
}

Result<ReplayReport> Replayer::run(const Sink& sink, const std::atomic<bool>* stop) {
  if (Status s = open(); !s) return s.error();
  const ReplayOptions& o = options_;
  auto& merger = prepared_->merger;
  runtime::ModuleHost& host = *host_;
  host.set_outlet(sink);
  ReplayReport report;

  // The delivered (remapped) name of each input channel; nodes are stable, so items point at the names.
  std::unordered_map<std::string, std::string> delivered_name;
  auto deliver_as = [&](const std::string& input) -> const std::string* {
    auto it = delivered_name.find(input);
    if (it == delivered_name.end()) {
      std::string name = input;
      for (const auto& [from, to] : o.remap) {
        if (name == from) {
          name = to;
          break;
        }
      }
      it = delivered_name.emplace(input, std::move(name)).first;
    }
    return &it->second;
  };

  std::unordered_map<std::string, StreamFaultInjector> injectors;
  std::unordered_map<std::string, int64_t> unstamped_seq;
  if (o.inject) {
    for (const auto& [channel, f] : o.inject->streams) {
      injectors.emplace(channel, StreamFaultInjector(channel, f, o.inject->seed, merger->base().us()));
    }
  }

  ItemHeap arrivals;  // inputs delayed by injected latency, by arrival
  ItemHeap stamped;   // --order stamp: inputs waiting for stragglers, by stamp
  int64_t order = 0;
  Time latest_arrival = Time::min();
  const Duration window = Duration::from_seconds_rounded(o.reorder_window_s);
  std::vector<Delivery> deliveries;
  Status failure;

  auto to_modules = [&](Item&& item) -> Status {
    if (o.order == Order::kReceived) return deliver(host, o, report, item);
    latest_arrival = std::max(latest_arrival, item.time);
    if (auto stamp = lcmtypes::header_stamp(item.data(), item.time.us())) item.time = Time::from_us(*stamp);
    stamped.push(std::move(item));
    while (!stamped.empty() && stamped.top().time <= latest_arrival - window) {
      if (Status s = deliver(host, o, report, stamped.top()); !s) return s;
      stamped.pop();
    }
    return {};
  };
  // Delayed inputs whose arrival has come, up to time t.
  auto release = [&](Time t) -> Status {
    while (!arrivals.empty() && arrivals.top().time <= t) {
      Item item = std::move(const_cast<Item&>(arrivals.top()));
      arrivals.pop();
      if (Status s = to_modules(std::move(item)); !s) return s;
    }
    return {};
  };

  Event e;
  while (!(stop != nullptr && stop->load()) && merger->next(e)) {
    ++report.read;
    if (o.progress && report.read % 4096 == 0) {
      const auto [done, total] = merger->bytes();
      o.progress(done, total);
    }
    const std::string input(e.channel);
    Item item;
    item.time = Time::from_us(e.utime);
    item.order = order++;
    item.channel = deliver_as(input);
    item.view = e.data;
    if (auto r = o.restamp.find(input); r != o.restamp.end()) {
      const ClockCorrection& c = r->second;
      item.owned.assign(e.data.begin(), e.data.end());
      const bool stamped_msg = lcmtypes::map_stamps(
          item.owned, e.utime, [&](int64_t s) { return corrected_stamp(c, s, merger->base().us()); });
      if (!stamped_msg) item.owned.clear();
    }
    if (auto inj = injectors.find(input); inj != injectors.end()) {
      const auto header = lcmtypes::read_header(item.data(), e.utime);
      const int64_t seq = header ? header->seq : unstamped_seq[input]++;
      deliveries.clear();
      inj->second.apply(seq, e.utime, deliveries);
      for (const Delivery& d : deliveries) {
        Item copy;
        copy.time = Time::from_us(d.arrival_utime);
        copy.order = order++;
        copy.channel = item.channel;
        copy.owned = item.owned;
        copy.view = item.view;
        if (const int64_t shift = d.stamp_utime - e.utime; shift != 0) {  // the injected clock offset and drift
          if (copy.owned.empty()) copy.owned.assign(e.data.begin(), e.data.end());
          if (!lcmtypes::map_stamps(copy.owned, e.utime, [&](int64_t s) { return s + shift; })) copy.owned = item.owned;
        }
        arrivals.push(std::move(copy));
      }
    } else {
      arrivals.push(std::move(item));
    }
    const auto next = merger->peek();
    if (Status s = release(next.value_or(Time::max())); !s) {
      failure = s;
      break;
    }
  }
  const bool interrupted = stop != nullptr && stop->load();
  if (failure.ok() && !interrupted) failure = release(Time::max());
  while (failure.ok() && !stamped.empty()) {
    failure = deliver(host, o, report, stamped.top());
    stamped.pop();
  }
  std::vector<driftlab::fault_t> injected;
  for (const auto& [channel, inj] : injectors) {
    for (auto& f : inj.manifest(report.end_utime)) injected.push_back(std::move(f));
  }
  std::sort(injected.begin(), injected.end(), [](const fault_t& a, const fault_t& b) {
    return a.channel != b.channel ? a.channel < b.channel : a.kind < b.kind;
  });
  if (failure.ok()) failure = host.finish();
  if (failure.ok() && !injected.empty()) {
    failure = host.record(o.faults_channel, encode_manifest(o, host.now().us(), injected), true, false);
  }
  Status closed = host.close();
  if (!failure.ok()) return failure.error();
  if (!closed.ok()) return closed.error();
  report.outputs = host.outputs();
  report.log_problems = merger->problems();
  report.interrupted = interrupted;
  report.modules = host.reports();
  report.injected = std::move(injected);
  return report;
}

}  // namespace driftlab::replay
