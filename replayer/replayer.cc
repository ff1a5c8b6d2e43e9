#include "replayer/replayer.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <fstream>
#include <queue>
#include <regex>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "core/internal/yaml_fields.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/log_writer.h"
#include "driftlab/fault_manifest_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"
#include "replayer/internal/module_tally.h"

namespace driftlab::replay {

Result<Restamp> load_restamp(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{path + ": cannot open the restamp file"};
  std::stringstream text;
  text << in.rdbuf();
  try {
    const YAML::Node root = YAML::Load(text.str());
    Fields top(root, path, "");
    DL_TRY(top.is_map());
    Restamp r;
    const YAML::Node channels = top.node("channels");
    if (!channels.IsDefined() || !channels.IsMap()) {
      return Error{at(path, root) + ": a restamp file needs 'channels: {CHANNEL: {offset_s: ..., drift_ppm: ...}}'"};
    }
    for (const auto& kv : channels) {
      const std::string channel = kv.first.as<std::string>();
      Fields f(kv.second, path, "channels." + channel);
      DL_TRY(f.is_map());
      ClockCorrection c;
      DL_TRY(f.number("offset_s", c.offset_s, -86400, 86400));
      DL_TRY(f.number("drift_ppm", c.drift_ppm, -1e5, 1e5));
      double ref = 0;
      DL_TRY(f.number("reference_utime", ref, 0, 1e19));
      c.reference_utime = static_cast<int64_t>(ref);
      DL_TRY(f.finish("offset_s, drift_ppm, reference_utime"));
      r[channel] = c;
    }
    DL_TRY(top.finish("channels"));
    return r;
  } catch (const YAML::Exception& e) {
    return Error{path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
}

namespace {

constexpr int64_t kUs = 1000000;

/// An input on its way to the modules.
struct Item {
  int64_t time = 0;      ///< delivery time [us]
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

class Engine;

/// One module's view of the bus, and what the replayer measures about it.
class ModuleBus final : public Bus {
 public:
  ModuleBus(Engine& engine, Module& module, size_t index) : engine_(engine), module_(module), index_(index) {}
  void subscribe(const std::string& channel_regex, BusHandler handler) override;
  void publish(std::string_view channel, std::span<const uint8_t> data) override;
  int64_t now() const override;
  void every(int64_t period_us, std::function<void()> fn) override;
  std::string artifact_prefix() const override;

  struct Subscription {
    std::regex regex;
    BusHandler handler;
  };
  Engine& engine_;
  Module& module_;
  size_t index_;
  std::vector<Subscription> subs_;
  internal::ModuleTally tally_;
};

class Engine {
 public:
  explicit Engine(const ReplayOptions& o) : o_(o) {}
  void set_sink(Sink sink) { sink_ = std::move(sink); }

  Status start(std::vector<std::unique_ptr<Module>>& modules) {
    for (size_t i = 0; i < modules.size(); ++i) buses_.push_back(std::make_unique<ModuleBus>(*this, *modules[i], i));
    if (!o_.out.empty()) {
      std::string prefix = o_.out;
      if (prefix.size() > 4 && prefix.compare(prefix.size() - 4, 4, ".lcm") == 0) prefix.resize(prefix.size() - 4);
      prefix_ = prefix;
    }
    for (auto& b : buses_) {
      if (Status s = b->module_.start(*b); !s) return Error{"module " + b->module_.name() + ": " + s.message()};
    }
    if (!o_.out.empty()) {
      auto w = LogWriter::create(o_.out, {.atomic = true});
      if (!w) return w.error();
      writer_.emplace(std::move(*w));
    }
    return {};
  }

  void add_timer(int64_t period, std::function<void()> fn) { timers_.push_back({period, 0, std::move(fn)}); }

  /// Delivers one input at its time, then everything it caused.
  Status deliver(const Item& item) {
    if (Status s = fire_timers(item.time); !s) return s;
    now_ = std::max(now_, item.time);
    if (report_.dispatched == 0) report_.start_utime = now_;
    report_.end_utime = now_;
    ++report_.dispatched;
    ++report_.channels[*item.channel];
    if (Status s = maybe_stats(); !s) return s;
    if (o_.write_inputs) {
      if (Status s = write(*item.channel, item.data()); !s) return s;
    }
    emit(*item.channel, item.data());
    dispatch(*item.channel, item.data());
    return drain();
  }

  /// Calls every module's finish(), the last statistics and the manifest of injected faults.
  Status finish(const std::vector<driftlab::fault_t>& injected) {
    for (auto& b : buses_) {
      try {
        b->module_.finish(*b);
      } catch (const std::exception& e) {  // as for a message: counted and named, the run and its log complete
        b->tally_.failed("(finish)", e.what());
      }
      if (Status s = drain(); !s) return s;
    }
    if (Status s = publish_stats(); !s) return s;
    if (!injected.empty()) {
      driftlab::fault_manifest_t m;
      m.header.utime = now_;
      m.header.seq = 0;
      m.seed = static_cast<int64_t>(o_.inject ? o_.inject->seed : 0);
      m.faults = injected;
      m.nfaults = static_cast<int32_t>(m.faults.size());
      std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
      m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
      if (Status s = write(o_.faults_channel, bytes); !s) return s;
    }
    return {};
  }

  Status close() {
    if (!writer_) return {};
    Status s = writer_->close();
    writer_.reset();
    return s;
  }

  std::vector<ModuleReport> module_reports() const {
    std::vector<ModuleReport> out;
    for (const auto& b : buses_) out.push_back(b->tally_.report(b->module_));
    return out;
  }

  ReplayReport& report() { return report_; }
  int64_t now() const { return now_; }
  const std::string& prefix() const { return prefix_; }
  void invalidate_routes() { routes_.clear(); }

  void publish(ModuleBus& from, std::string_view channel, std::span<const uint8_t> data) {
    from.tally_.output();
    ++report_.outputs;
    pending_.push_back({std::string(channel), std::vector<uint8_t>(data.begin(), data.end())});
  }

 private:
  struct Route {
    ModuleBus* bus;
    size_t sub;
  };
  struct Pending {
    std::string channel;
    std::vector<uint8_t> data;
  };

  struct Timer {
    int64_t period;
    int64_t next;  ///< 0: not yet placed
    std::function<void()> fn;
  };

  /// Fires, in time order, every timer tick before time t (and the ones at t, before the message at t).
  Status fire_timers(int64_t t) {
    for (;;) {
      Timer* due = nullptr;
      for (Timer& timer : timers_) {
        if (timer.next == 0) {
          const int64_t from = std::max(now_, t);
          timer.next = (from / timer.period + (from % timer.period != 0 ? 1 : 0)) * timer.period;
        }
        if (timer.next <= t && (due == nullptr || timer.next < due->next)) due = &timer;
      }
      if (due == nullptr) return {};
      now_ = std::max(now_, due->next);
      due->next += due->period;
      due->fn();
      if (Status s = drain(); !s) return s;
    }
  }

  const std::vector<Route>& routes(const std::string& channel) {
    auto it = routes_.find(channel);
    if (it != routes_.end()) return it->second;
    std::vector<Route> r;
    for (auto& b : buses_) {
      for (size_t i = 0; i < b->subs_.size(); ++i) {
        if (std::regex_match(channel, b->subs_[i].regex)) r.push_back({b.get(), i});
      }
    }
    return routes_.emplace(channel, std::move(r)).first->second;
  }

  /// The interned name of a channel, stable for the run (statistics key on it).
  const std::string* intern(const std::string& channel) {
    return &*names_.insert(channel).first;
  }

  void dispatch(const std::string& channel, std::span<const uint8_t> data) {
    const std::vector<Route> targets = routes(channel);  // a copy: handlers may subscribe (and clear the cache)
    if (targets.empty()) return;
    const std::string* name = intern(channel);
    // A message that does not hold its type's layout never reaches a decoder: it is counted and dropped.
    if (const auto why = lcmtypes::layout_problem(data)) {
      for (const Route& r : targets) r.bus->tally_.malformed(channel, *why);
      return;
    }
    const auto stamp = lcmtypes::header_stamp(data, now_);
    BusMessage m{channel, now_, data};
    for (const Route& r : targets) {
      ModuleBus& b = *r.bus;
      b.tally_.input(name, stamp);
      const auto t0 = o_.timing ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
      try {
        b.subs_[r.sub].handler(m);
      } catch (const std::exception& e) {  // one message a module cannot take must not end the run
        b.tally_.failed(channel, e.what());
      }
      if (o_.timing) {
        b.tally_.processed(now_, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      } else {
        b.tally_.unmeasured();
      }
    }
  }

  /// Delivers what the modules published, in publication order, at the current time.
  Status drain() {
    while (!pending_.empty()) {
      Pending p = std::move(pending_.front());
      pending_.pop_front();
      if (Status s = write(p.channel, p.data); !s) return s;
      emit(p.channel, p.data);
      dispatch(p.channel, p.data);
    }
    return {};
  }

  Status write(const std::string& channel, std::span<const uint8_t> data) {
    if (!writer_) return {};
    return writer_->write(now_, channel, data);
  }

  void emit(std::string_view channel, std::span<const uint8_t> data) {
    if (sink_) sink_(BusMessage{channel, now_, data});
  }

  Status maybe_stats() {
    const auto period = static_cast<int64_t>(o_.stats_period_s * kUs);
    if (period <= 0) return {};
    if (next_stats_ == 0) next_stats_ = now_ + period;
    if (now_ < next_stats_) return {};
    while (next_stats_ <= now_) next_stats_ += period;
    if (Status s = publish_stats(); !s) return s;
    return drain();
  }

  Status publish_stats() {
    if (buses_.empty()) return {};
    for (auto& b : buses_) {
      const auto bytes = internal::encode_stats(b->tally_.report(b->module_), stats_seq_, now_);
      if (Status s = write(o_.stats_channel, bytes); !s) return s;
      emit(o_.stats_channel, bytes);
    }
    ++stats_seq_;
    return {};
  }

  const ReplayOptions& o_;
  Sink sink_;
  std::vector<std::unique_ptr<ModuleBus>> buses_;
  std::unordered_map<std::string, std::vector<Route>> routes_;
  std::unordered_set<std::string> names_;
  std::deque<Pending> pending_;
  std::vector<Timer> timers_;
  std::optional<LogWriter> writer_;
  std::string prefix_;
  int64_t now_ = std::numeric_limits<int64_t>::min();
  int64_t next_stats_ = 0;
  int64_t stats_seq_ = 0;
  ReplayReport report_;
};

void ModuleBus::subscribe(const std::string& channel_regex, BusHandler handler) {
  subs_.push_back({std::regex(channel_regex, std::regex::ECMAScript | std::regex::optimize), std::move(handler)});
  engine_.invalidate_routes();
}
void ModuleBus::publish(std::string_view channel, std::span<const uint8_t> data) {
  engine_.publish(*this, channel, data);
}
int64_t ModuleBus::now() const { return engine_.now(); }
void ModuleBus::every(int64_t period_us, std::function<void()> fn) {
  if (period_us <= 0) std::abort();  // a broken invariant: modules validate their rates
  engine_.add_timer(period_us, std::move(fn));
}
std::string ModuleBus::artifact_prefix() const { return engine_.prefix(); }

/// The logs merged by log time, with -c, --start and --end applied.
class Merger {
 public:
  static Result<Merger> open(const ReplayOptions& o, std::function<void(const Problem&)> on_problem) {
    Merger m;
    for (const auto& path : o.logs) {
      ReadOptions ro;
      ro.channels = o.channels;
      ro.on_problem = on_problem;
      auto r = LogReader::open(path, ro);
      if (!r) return r.error();
      m.sources_.push_back({std::move(*r), {}, false});
    }
    int64_t first = std::numeric_limits<int64_t>::max();
    for (auto& s : m.sources_) {
      s.has = s.reader.next(s.event);
      if (s.has) first = std::min(first, s.event.utime);
    }
    if (first == std::numeric_limits<int64_t>::max()) return m;  // nothing to replay
    m.base_ = first;
    // Offsets from the first event, saturated: 1e308 s is past any log, not an overflow back before its start.
    auto after_first = [first](double seconds) {
      const double us = seconds * kUs;
      const double room = static_cast<double>(std::numeric_limits<int64_t>::max() - first);
      return us >= room ? std::numeric_limits<int64_t>::max() : first + static_cast<int64_t>(std::llround(us));
    };
    if (o.start_s > 0) {
      const int64_t from = after_first(o.start_s);
      for (auto& s : m.sources_) {
        if (s.has && s.event.utime >= from) continue;
        if (Status st = s.reader.seek(from); !st) return Error{st.message()};
        s.has = s.reader.next(s.event);
      }
    }
    if (std::isfinite(o.end_s)) m.end_ = after_first(o.end_s);
    return m;
  }

  /// The time of the next event, or nullopt at the end.
  std::optional<int64_t> peek() {
    const Source* s = best();
    if (s == nullptr) return std::nullopt;
    return s->event.utime;
  }
  bool next(Event& out) {
    Source* s = best();
    if (s == nullptr) return false;
    out = s->event;
    s->has = s->reader.next(s->event);
    return true;
  }
  int64_t base() const { return base_; }
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
      if (s.has && s.event.utime > end_) s.has = false;
      if (s.has && (b == nullptr || s.event.utime < b->event.utime)) b = &s;
    }
    return b;
  }
  Merger() = default;
  std::vector<Source> sources_;
  int64_t base_ = 0;
  int64_t end_ = std::numeric_limits<int64_t>::max();
};

}  // namespace

struct Replayer::Prepared {
  std::optional<Merger> merger;
  std::unique_ptr<Engine> engine;
};

bool delivers(const ReplayOptions& o, const std::string& channel, const std::string& type) {
  // The input channels delivered as `channel`: those remapped to it, and itself unless remapped away. The first
  // rule naming an input applies, as in run().
  auto delivered_as = [&o](const std::string& input) {
    for (const auto& [from, to] : o.remap) {
      if (input == from) return to;
    }
    return input;
  };
  std::vector<std::string> sources;
  if (delivered_as(channel) == channel) sources.push_back(channel);
  for (const auto& [from, to] : o.remap) {
    if (to == channel && delivered_as(from) == channel) sources.push_back(from);
  }
  static const std::regex special(R"([.^$|()\[\]{}*+?\\])");
  for (const auto& source : sources) {
    try {
      if (!o.channels.empty() && !std::regex_match(source, std::regex(o.channels))) continue;  // filtered out
    } catch (const std::regex_error&) {
      return false;  // open() reports the bad regex
    }
    for (const auto& log : o.logs) {
      auto r = LogReader::open(log, {.channels = std::regex_replace(source, special, R"(\$&)")});
      Event e;
      if (r && r->next(e)) {
        const char* name = lcmtypes::type_name(logfmt::fingerprint(e.data));
        if (name != nullptr && type == name) return true;
      }
    }
  }
  return false;
}

Replayer::Replayer(ReplayOptions options) : options_(std::move(options)) {}
Replayer::~Replayer() = default;
void Replayer::add_module(std::unique_ptr<Module> module) { modules_.push_back(std::move(module)); }

Status Replayer::open() {
  if (prepared_) return {};
  const ReplayOptions& o = options_;
  for (const auto& [from, to] : o.remap) {
    if (from.empty() || to.empty()) return Error{"--remap " + from + "=" + to + ": both names must be non-empty"};
  }
  auto merger = Merger::open(o, nullptr);
  if (!merger) return merger.error();
  auto engine = std::make_unique<Engine>(o);
  if (Status s = engine->start(modules_); !s) return s;
  prepared_ = std::make_unique<Prepared>();
  prepared_->merger.emplace(std::move(*merger));
  prepared_->engine = std::move(engine);
  return {};
}

Result<ReplayReport> Replayer::run(const Sink& sink, const std::atomic<bool>* stop) {
  if (Status s = open(); !s) return Error{s.message()};
  const ReplayOptions& o = options_;
  auto& merger = prepared_->merger;
  Engine& engine = *prepared_->engine;
  engine.set_sink(sink);

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
      injectors.emplace(channel, StreamFaultInjector(channel, f, o.inject->seed, merger->base()));
    }
  }

  ItemHeap arrivals;  // inputs delayed by injected latency, by arrival
  ItemHeap stamped;   // --order stamp: inputs waiting for stragglers, by stamp
  int64_t order = 0;
  int64_t latest_arrival = std::numeric_limits<int64_t>::min();
  const auto window = static_cast<int64_t>(std::llround(o.reorder_window_s * kUs));
  std::vector<Delivery> deliveries;
  Status failure;

  auto to_modules = [&](Item&& item) -> Status {
    if (o.order == Order::kReceived) return engine.deliver(item);
    latest_arrival = std::max(latest_arrival, item.time);
    if (auto stamp = lcmtypes::header_stamp(item.data(), item.time)) item.time = *stamp;
    stamped.push(std::move(item));
    while (!stamped.empty() && stamped.top().time <= latest_arrival - window) {
      if (Status s = engine.deliver(stamped.top()); !s) return s;
      stamped.pop();
    }
    return {};
  };
  // Delayed inputs whose arrival has come, up to time t.
  auto release = [&](int64_t t) -> Status {
    while (!arrivals.empty() && arrivals.top().time <= t) {
      Item item = std::move(const_cast<Item&>(arrivals.top()));
      arrivals.pop();
      if (Status s = to_modules(std::move(item)); !s) return s;
    }
    return {};
  };

  Event e;
  while (!(stop != nullptr && stop->load()) && merger->next(e)) {
    ++engine.report().read;
    const std::string input(e.channel);
    Item item;
    item.time = e.utime;
    item.order = order++;
    item.channel = deliver_as(input);
    item.view = e.data;
    if (auto r = o.restamp.find(input); r != o.restamp.end()) {
      const ClockCorrection& c = r->second;
      const int64_t ref = c.reference_utime != 0 ? c.reference_utime : merger->base();
      item.owned.assign(e.data.begin(), e.data.end());
      const bool stamped_msg = lcmtypes::map_stamps(item.owned, e.utime, [&](int64_t s) {
        const double correction = c.offset_s + c.drift_ppm * 1e-6 * static_cast<double>(s - ref) * 1e-6;
        return s - static_cast<int64_t>(std::llround(correction * kUs));
      });
      if (!stamped_msg) item.owned.clear();
    }
    if (auto inj = injectors.find(input); inj != injectors.end()) {
      const auto stamp = lcmtypes::header_stamp(item.data(), e.utime);
      int64_t seq = stamp ? static_cast<int64_t>(logfmt::load_be64(item.data().data() + 8)) : unstamped_seq[input]++;
      deliveries.clear();
      inj->second.apply(seq, e.utime, deliveries);
      for (const Delivery& d : deliveries) {
        Item copy;
        copy.time = d.arrival_utime;
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
    if (Status s = release(next ? *next : std::numeric_limits<int64_t>::max()); !s) {
      failure = s;
      break;
    }
  }
  const bool interrupted = stop != nullptr && stop->load();
  if (failure.ok() && !interrupted) failure = release(std::numeric_limits<int64_t>::max());
  while (failure.ok() && !stamped.empty()) {
    failure = engine.deliver(stamped.top());
    stamped.pop();
  }
  std::vector<driftlab::fault_t> injected;
  for (const auto& [channel, inj] : injectors) {
    for (auto& f : inj.manifest(engine.report().end_utime)) injected.push_back(std::move(f));
  }
  std::sort(injected.begin(), injected.end(), [](const fault_t& a, const fault_t& b) {
    return a.channel != b.channel ? a.channel < b.channel : a.kind < b.kind;
  });
  if (failure.ok()) failure = engine.finish(injected);
  Status closed = engine.close();
  if (!failure.ok()) return Error{failure.message()};
  if (!closed.ok()) return Error{closed.message()};
  ReplayReport report = std::move(engine.report());
  report.log_problems = merger->problems();
  report.interrupted = interrupted;
  report.modules = engine.module_reports();
  report.injected = std::move(injected);
  return report;
}

}  // namespace driftlab::replay
