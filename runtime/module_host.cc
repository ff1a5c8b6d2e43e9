#include "runtime/module_host.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <regex>

#include "core/check.h"
#include "core/log_writer.h"
#include "core/wall_clock.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "runtime/internal/module_tally.h"

namespace driftlab::runtime {
namespace {

class FileLog final : public LogSink {
 public:
  explicit FileLog(LogWriter writer) : writer_(std::move(writer)) {}
  Status write(int64_t utime, std::string_view channel, std::span<const uint8_t> data) override {
    return writer_.write(utime, channel, data);
  }
  Status close() override { return writer_.close(); }

 private:
  LogWriter writer_;
};

}  // namespace

Result<std::unique_ptr<LogSink>> open_log_file(const std::string& path) {
  auto w = LogWriter::create(path, {.atomic = true});
  if (!w) return w.error();
  return std::unique_ptr<LogSink>(std::make_unique<FileLog>(std::move(*w)));
}

/// One module's view of the host, and what the host counts about it.
class ModuleHost::HostBus final : public Bus {
 public:
  HostBus(ModuleHost& host, Module& module) : host_(host), module_(module) {}
  void subscribe(const std::string& channel_regex, BusHandler handler) override {
    subs_.push_back(
        {channel_regex, std::regex(channel_regex, std::regex::ECMAScript | std::regex::optimize), std::move(handler)});
    host_.routes_.clear();
  }
  void publish(std::string_view channel, std::span<const uint8_t> data) override {
    host_.publish(*this, channel, data);
  }
  Time now() const override { return host_.now(); }
  void every(Duration period, std::function<void()> fn) override {
    DRIFTLAB_CHECK(period.us() > 0, "a timer's period is positive (modules validate their rates)");
    host_.timers_.push_back({period.us(), 0, std::move(fn), this});
  }
  std::string artifact_prefix() const override { return host_.prefix_; }

  struct Subscription {
    std::string pattern;
    std::regex regex;
    BusHandler handler;
  };
  ModuleHost& host_;
  Module& module_;
  std::vector<Subscription> subs_;
  internal::ModuleTally tally_;
};

ModuleHost::ModuleHost(HostOptions options) : o_(std::move(options)) {}
ModuleHost::~ModuleHost() = default;

void ModuleHost::add_module(std::unique_ptr<Module> module) { modules_.push_back(std::move(module)); }

Status ModuleHost::start(std::unique_ptr<LogSink> log) {
  if (Status s = start_modules(); !s) return s;
  return open_log(std::move(log));
}

Status ModuleHost::start_modules() {
  if (started_) return started_status_;
  started_ = true;
  for (auto& m : modules_) buses_.push_back(std::make_unique<HostBus>(*this, *m));
  if (!o_.out.empty()) {
    prefix_ = o_.out;
    if (prefix_.size() > 4 && prefix_.compare(prefix_.size() - 4, 4, ".lcm") == 0) prefix_.resize(prefix_.size() - 4);
  }
  for (auto& b : buses_) {
    if (Status s = b->module_.start(*b); !s) {
      started_status_ = Error{"module " + b->module_.name() + ": " + s.message()};
      return started_status_;
    }
  }
  return {};
}

Status ModuleHost::open_log(std::unique_ptr<LogSink> log) {
  if (log_) return {};
  if (log) {
    log_ = std::move(log);
  } else if (!o_.out.empty()) {
    auto file = open_log_file(o_.out);
    if (!file) return file.error();
    log_ = std::move(*file);
  }
  return {};
}

Status ModuleHost::advance(Time t) {
  if (Status s = fire_timers(t.us()); !s) return s;
  now_ = std::max(now_, t.us());
  return maybe_stats();
}

Status ModuleHost::deliver(std::string_view channel, std::span<const uint8_t> data) {
  dispatch(channel, data);
  return drain();
}

Status ModuleHost::record(std::string_view channel, std::span<const uint8_t> data, bool log, bool outlet) {
  if (log) {
    if (Status s = write(channel, data); !s) return s;
  }
  if (outlet && outlet_) outlet_(BusMessage{channel, now(), data});
  return {};
}

Status ModuleHost::finish() {
  for (auto& b : buses_) {
    try {
      b->module_.finish(*b);
    } catch (const std::exception& e) {  // as for a message: counted and named, the run and its log complete
      b->tally_.failed("(finish)", e.what());
    }
    if (Status s = drain(); !s) return s;
  }
  return publish_stats();
}

Status ModuleHost::close() {
  if (!log_) return {};
  Status s = log_->close();
  log_.reset();
  return s;
}

std::optional<Time> ModuleHost::next_due() const {
  std::optional<Time> due;
  auto earliest = [&due](int64_t t) { due = due ? std::min(*due, Time::from_us(t)) : Time::from_us(t); };
  for (const Timer& timer : timers_) {
    if (timer.next != INT64_MAX) earliest(timer.next == 0 ? now_ : timer.next);  // unplaced: at the next advance
  }
  if (o_.stats_period_s > 0 && next_stats_ != 0) earliest(next_stats_);
  return due;
}

std::vector<std::string> ModuleHost::subscriptions() const {
  std::vector<std::string> out;
  for (const auto& b : buses_) {
    for (const auto& s : b->subs_) out.push_back(s.pattern);
  }
  return out;
}

std::vector<ModuleReport> ModuleHost::reports() const {
  std::vector<ModuleReport> out;
  for (const auto& b : buses_) out.push_back(b->tally_.report(b->module_));
  return out;
}

void ModuleHost::publish(HostBus& from, std::string_view channel, std::span<const uint8_t> data) {
  from.tally_.output();
  ++outputs_;
  if (o_.loopback) {
    pending_.push_back({std::string(channel), std::vector<uint8_t>(data.begin(), data.end())});
  } else {
    (void)record(channel, data, true, true);  // a write failure is kept in failure_
  }
}

/// Fires, in time order, every timer tick up to t (those at t before the message at t). A timer is placed on its
/// first whole multiple of the period at or after the time it is first seen here. Ticks run out at the end of
/// int64_t, and a jump of more than kMaxCatchUpTicks ticks (a log time far ahead: a corrupt stamp, a clock stepped
/// by years, which would take billions of ticks) goes straight to the last tick before t, counted as skipped.
Status ModuleHost::fire_timers(int64_t t) {
  constexpr int64_t kSpent = INT64_MAX;
  constexpr uint64_t kMaxCatchUpTicks = 1'000'000;  // 14 h of a 20 Hz controller, 17 min of a 1 kHz timer
  for (;;) {
    Timer* due = nullptr;
    for (Timer& timer : timers_) {
      if (timer.next == 0) {
        const int64_t from = std::max(now_, t);
        const int64_t whole = from / timer.period + (from % timer.period != 0 ? 1 : 0);
        if (__builtin_mul_overflow(whole, timer.period, &timer.next)) timer.next = kSpent;
      }
      if (timer.next == kSpent) continue;
      if (timer.next <= t && (due == nullptr || timer.next < due->next)) due = &timer;
    }
    if (due == nullptr) return {};
    // t >= next: exact whatever the two are.
    const uint64_t behind = us_after(due->next, t) / static_cast<uint64_t>(due->period);
    // The last tick at or before t, in uint64_t: behind * period can pass INT64_MAX (a tick far in the past and t
    // far ahead), while the sum, at most t, cannot; unsigned arithmetic wraps to it exactly.
    const auto last_tick = [&] {
      return static_cast<int64_t>(static_cast<uint64_t>(due->next) + behind * static_cast<uint64_t>(due->period));
    };
    if (o_.clock == HostClock::kWall) {
      due->next = last_tick();  // the latest only
    } else if (behind > kMaxCatchUpTicks) {
      const int64_t from = due->next;
      due->next = last_tick();
      due->bus->tally_.skipped(static_cast<int64_t>(behind), from, due->next);
    }
    now_ = std::max(now_, due->next);
    const int64_t tick = due->next;
    if (__builtin_add_overflow(tick, due->period, &due->next)) due->next = kSpent;
    try {
      due->fn();                         // timers_ is a deque: a timer may add timers without moving this one
    } catch (const std::exception& e) {  // as for a message: counted, and the run goes on
      due->bus->tally_.failed("a timer", e.what());
    }
    if (Status s = drain(); !s) return s;
  }
}

const std::vector<ModuleHost::Route>& ModuleHost::routes(std::string_view channel) {
  auto it = routes_.find(channel);
  if (it != routes_.end()) return it->second;
  std::vector<Route> r;
  for (auto& b : buses_) {
    for (size_t i = 0; i < b->subs_.size(); ++i) {
      if (std::regex_match(channel.begin(), channel.end(), b->subs_[i].regex)) r.push_back({b.get(), i});
    }
  }
  return routes_.emplace(std::string(channel), std::move(r)).first->second;
}

void ModuleHost::dispatch(std::string_view channel, std::span<const uint8_t> data) {
  const std::vector<Route> targets = routes(channel);  // a copy: handlers may subscribe (and clear the cache)
  if (targets.empty()) return;
  deliveries_ += static_cast<int64_t>(targets.size());
  auto known = names_.find(channel);
  if (known == names_.end()) known = names_.emplace(channel).first;
  const std::string* name = &*known;
  // A message that does not hold its type's layout never reaches a decoder: it is counted and dropped.
  if (const auto why = lcmtypes::layout_problem(data)) {
    for (const Route& r : targets) r.bus->tally_.malformed(*name, *why);
    return;
  }
  const auto stamp = lcmtypes::header_stamp(data, now_);
  const BusMessage m{*name, now(), data};
  for (const Route& r : targets) {
    HostBus& b = *r.bus;
    b.tally_.input(name, stamp);
    std::optional<Stopwatch> watch;
    if (o_.timing) watch.emplace();
    try {
      b.subs_[r.sub].handler(m);
    } catch (const std::exception& e) {  // one message a module cannot take must not end the run
      b.tally_.failed(*name, e.what());
    }
    if (watch) {
      b.tally_.processed(now_, watch->seconds());
    } else {
      b.tally_.unmeasured();
    }
  }
}

/// Delivers what the modules published, in publication order, at the current time.
Status ModuleHost::drain() {
  while (!pending_.empty()) {
    Pending p = std::move(pending_.front());
    pending_.pop_front();
    if (Status s = record(p.channel, p.data, true, true); !s) return s;
    dispatch(p.channel, p.data);
  }
  return {};
}

Status ModuleHost::write(std::string_view channel, std::span<const uint8_t> data) {
  if (!log_ || !failure_.ok()) return failure_;
  if (Status s = log_->write(now_, channel, data); !s) failure_ = s;
  return failure_;
}

Status ModuleHost::maybe_stats() {
  const int64_t period = Duration::from_seconds_truncated(o_.stats_period_s).us();
  if (period <= 0) return {};
  if (next_stats_ == 0) next_stats_ = now_ + period;
  if (now_ < next_stats_) return {};
  while (next_stats_ <= now_) next_stats_ += period;
  if (Status s = publish_stats(); !s) return s;
  return drain();
}

Status ModuleHost::publish_stats() {
  if (buses_.empty()) return {};
  for (auto& b : buses_) {
    const auto bytes = internal::encode_stats(b->tally_.report(b->module_), stats_seq_, now_);
    if (Status s = record(o_.stats_channel, bytes, true, true); !s) return s;
  }
  ++stats_seq_;
  return {};
}

}  // namespace driftlab::runtime
