#include "replayer/live_runner.h"

#include <lcm/lcm.h>
#include <sys/time.h>

#include <chrono>
#include <optional>
#include <unordered_set>

#include "core/log_writer.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "replayer/internal/module_tally.h"

namespace driftlab::replay {
namespace {

int64_t wall_utime() {
  timeval tv{};
  gettimeofday(&tv, nullptr);
  return static_cast<int64_t>(tv.tv_sec) * 1000000 + tv.tv_usec;
}

/// One module's view of the live bus.
class LiveBus final : public Bus {
 public:
  LiveBus(LiveRunner::Impl& runner, Module& module) : runner_(runner), module_(module) {}
  void subscribe(const std::string& channel_regex, BusHandler handler) override;
  void publish(std::string_view channel, std::span<const uint8_t> data) override;
  int64_t now() const override { return handling_ != 0 ? handling_ : wall_utime(); }
  void every(int64_t period_us, std::function<void()> fn) override;
  std::string artifact_prefix() const override;

  struct Subscription {
    LiveBus* bus;
    BusHandler handler;
  };
  LiveRunner::Impl& runner_;
  Module& module_;
  std::vector<std::unique_ptr<Subscription>> subs_;
  internal::ModuleTally tally_;
  int64_t handling_ = 0;  ///< receive time of the message being handled, 0 outside handlers [us]
};

}  // namespace

struct LiveRunner::Impl {
  LiveOptions o;
  std::vector<std::unique_ptr<Module>> modules;
  std::vector<std::unique_ptr<LiveBus>> buses;
  lcm_t* lcm = nullptr;
  std::optional<LogWriter> writer;
  std::string prefix;
  std::unordered_set<std::string> names;  ///< interned channel names
  struct Timer {
    int64_t period, next;
    std::function<void()> fn;
  };
  std::vector<Timer> timers;
  int64_t received = 0, outputs = 0, stats_seq = 0;
  Status failure;

  ~Impl() {
    if (lcm != nullptr) lcm_destroy(lcm);
  }

  void record(std::string_view channel, std::span<const uint8_t> data, int64_t utime) {
    if (!writer || !failure.ok()) return;
    if (Status s = writer->write(utime, channel, data); !s) failure = s;
  }

  void publish_stats() {
    const int64_t now = wall_utime();
    for (auto& b : buses) {
      const auto bytes = internal::encode_stats(b->tally_.report(b->module_), stats_seq, now);
      lcm_publish(lcm, o.stats_channel.c_str(), bytes.data(), static_cast<unsigned int>(bytes.size()));
      record(o.stats_channel, bytes, now);
    }
    ++stats_seq;
  }
};

namespace {

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* sub = static_cast<LiveBus::Subscription*>(user);
  LiveBus& b = *sub->bus;
  LiveRunner::Impl& r = b.runner_;
  ++r.received;
  const std::span<const uint8_t> data(static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
  // Any peer can publish: a message that does not hold its type's layout is counted and dropped, never decoded.
  if (const auto why = lcmtypes::layout_problem(data)) return b.tally_.malformed(channel, *why);
  const std::string* name = &*r.names.insert(channel).first;
  b.tally_.input(name, lcmtypes::header_stamp(data, rbuf->recv_utime));
  b.handling_ = rbuf->recv_utime;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    sub->handler(BusMessage{channel, rbuf->recv_utime, data});
  } catch (const std::exception& e) {  // an exception must not unwind through LCM's C code and end the run
    b.tally_.failed(channel, e.what());
  }
  b.tally_.processed(rbuf->recv_utime, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  b.handling_ = 0;
}

void LiveBus::subscribe(const std::string& channel_regex, BusHandler handler) {
  subs_.push_back(std::make_unique<Subscription>(Subscription{this, std::move(handler)}));
  lcm_subscribe(runner_.lcm, channel_regex.c_str(), &on_message, subs_.back().get());
}

void LiveBus::publish(std::string_view channel, std::span<const uint8_t> data) {
  const std::string name(channel);
  tally_.output();
  ++runner_.outputs;
  lcm_publish(runner_.lcm, name.c_str(), data.data(), static_cast<unsigned int>(data.size()));
  runner_.record(channel, data, now());
}

void LiveBus::every(int64_t period_us, std::function<void()> fn) {
  if (period_us <= 0) std::abort();  // a broken invariant: modules validate their rates
  const int64_t now = wall_utime();
  runner_.timers.push_back({period_us, (now / period_us + 1) * period_us, std::move(fn)});
}

std::string LiveBus::artifact_prefix() const { return runner_.prefix; }

}  // namespace

LiveRunner::LiveRunner(LiveOptions options) : impl_(std::make_unique<Impl>()) { impl_->o = std::move(options); }
LiveRunner::~LiveRunner() = default;
void LiveRunner::add_module(std::unique_ptr<Module> module) { impl_->modules.push_back(std::move(module)); }

Status LiveRunner::open() {
  Impl& d = *impl_;
  if (d.lcm != nullptr) return {};
  d.lcm = lcm_create(d.o.url.c_str());
  if (d.lcm == nullptr) return Error{"--url " + d.o.url + ": cannot open the LCM URL"};
  if (!d.o.out.empty()) {
    d.prefix = d.o.out;
    if (d.prefix.size() > 4 && d.prefix.compare(d.prefix.size() - 4, 4, ".lcm") == 0) d.prefix.resize(d.prefix.size() - 4);
  }
  for (auto& m : d.modules) {
    d.buses.push_back(std::make_unique<LiveBus>(d, *m));
    if (Status s = m->start(*d.buses.back()); !s) return Error{"module " + m->name() + ": " + s.message()};
  }
  if (!d.o.out.empty()) {
    auto w = LogWriter::create(d.o.out, {.atomic = true});
    if (!w) return w.error();
    d.writer.emplace(std::move(*w));
  }
  return {};
}

Result<LiveReport> LiveRunner::run(const std::atomic<bool>* stop) {
  if (Status s = open(); !s) return Error{s.message()};
  Impl& d = *impl_;
  const auto start = std::chrono::steady_clock::now();
  const auto period = static_cast<int64_t>(d.o.stats_period_s * 1e6);
  if (period > 0) d.timers.push_back({period, (wall_utime() / period + 1) * period, [&d] { d.publish_stats(); }});
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  while (!(stop != nullptr && stop->load()) && (d.o.duration_s <= 0 || elapsed() < d.o.duration_s) && d.failure.ok()) {
    // Wait for a message until the next timer is due (at most 100 ms, to notice a stop).
    int64_t wait_us = 100000;
    const int64_t now = wall_utime();
    for (const auto& t : d.timers) wait_us = std::min(wait_us, std::max<int64_t>(0, t.next - now));
    if (lcm_handle_timeout(d.lcm, static_cast<int>((wait_us + 999) / 1000)) < 0) {
      return Error{"--url " + d.o.url + ": receiving failed"};
    }
    const int64_t after = wall_utime();
    for (size_t i = 0; i < d.timers.size(); ++i) {  // by index: a timer may add timers
      if (d.timers[i].next > after) continue;
      while (d.timers[i].next <= after) d.timers[i].next += d.timers[i].period;
      auto fn = d.timers[i].fn;
      fn();
    }
  }
  for (auto& b : d.buses) {
    try {
      b->module_.finish(*b);
    } catch (const std::exception& e) {  // as for a message: counted and named, the log closed
      b->tally_.failed("(finish)", e.what());
    }
  }
  d.publish_stats();
  LiveReport report;
  report.received = d.received;
  report.outputs = d.outputs;
  report.wall_s = elapsed();
  for (auto& b : d.buses) report.modules.push_back(b->tally_.report(b->module_));
  Status closed = d.writer ? d.writer->close() : Status{};
  if (!d.failure.ok()) return Error{d.failure.message()};
  if (!closed.ok()) return Error{closed.message()};
  return report;
}

}  // namespace driftlab::replay
