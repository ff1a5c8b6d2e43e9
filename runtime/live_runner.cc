#include "runtime/live_runner.h"

#include <lcm/lcm.h>

#include <algorithm>

#include "runtime/module_host.h"

namespace driftlab::runtime {

struct LiveRunner::Impl {
  LiveOptions o;
  const WallClock& clock;  ///< moves the host between messages
  ModuleHost host;
  lcm_t* lcm = nullptr;
  Status failure;  ///< the first failure met inside LCM's callback

  Impl(LiveOptions options, const WallClock& wall_clock)
      : o(std::move(options)),
        clock(wall_clock),
        host({.clock = HostClock::kWall,
              .loopback = false,  // LCM brings what the modules publish back to them
              .out = o.out,
              .timing = true,  // nothing needs to repeat live
              .stats_period_s = o.stats_period_s,
              .stats_channel = o.stats_channel}) {}
  ~Impl() {
    if (lcm != nullptr) lcm_destroy(lcm);
  }

  /// Every message on a channel some module subscribed to goes to the host, which routes it.
  static void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
    auto& d = *static_cast<Impl*>(user);
    if (!d.failure.ok()) return;
    const std::span<const uint8_t> data(static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
    if (Status s = d.host.advance(Time::from_us(rbuf->recv_utime)); !s) d.failure = s;  // LCM's arrival stamp
    if (Status s = d.host.deliver(channel, data); !s) d.failure = s;
  }
};

LiveRunner::LiveRunner(LiveOptions options, const WallClock& clock)
    : impl_(std::make_unique<Impl>(std::move(options), clock)) {}
LiveRunner::~LiveRunner() = default;
void LiveRunner::add_module(std::unique_ptr<Module> module) { impl_->host.add_module(std::move(module)); }

Status LiveRunner::open() {
  Impl& d = *impl_;
  if (d.lcm != nullptr) return {};
  d.lcm = lcm_create(d.o.url.c_str());
  if (d.lcm == nullptr) return Error{"--url " + d.o.url + ": cannot open the LCM URL"};
  d.host.set_outlet([&d](const BusMessage& m) {
    const std::string channel(m.channel);
    lcm_publish(d.lcm, channel.c_str(), m.data.data(), static_cast<unsigned int>(m.data.size()));
  });
  if (Status s = d.host.start_modules(); !s) return s;
  // One LCM subscription to what any module subscribed to: LCM drops the other channels on arrival, and the host
  // routes the rest. Its queue holds as many messages as the modules' subscriptions would have had apiece (LCM's
  // default, 30, each), so a flood on one channel leaves room for the others as before.
  const std::vector<std::string> wanted = d.host.subscriptions();
  if (!wanted.empty()) {
    std::string any;
    for (const auto& regex : wanted) any += (any.empty() ? "(?:" : "|(?:") + regex + ")";
    lcm_subscription_t* sub = lcm_subscribe(d.lcm, ("(?:" + any + ")").c_str(), &Impl::on_message, &d);
    if (sub == nullptr) return Error{"--url " + d.o.url + ": cannot subscribe to " + any};
    lcm_subscription_set_queue_capacity(sub, static_cast<int>(30 * wanted.size()));
  }
  return d.host.open_log();  // after subscribing: a log on disk says the runner listens
}

Result<LiveReport> LiveRunner::run(const std::atomic<bool>* stop) {
  if (Status s = open(); !s) return s.error();
  Impl& d = *impl_;
  const Stopwatch running;
  auto failed = [&d] { return !d.failure.ok() || !d.host.failure().ok(); };
  while (!(stop != nullptr && stop->load()) && (d.o.duration_s <= 0 || running.seconds() < d.o.duration_s) &&
         !failed()) {
    const Time now = d.clock.now();
    if (Status s = d.host.advance(now); !s) break;  // timer ticks and statistics due by now
    // Wait for a message until the host is next due (at most 100 ms, to notice a stop).
    int64_t wait_us = 100000;
    if (const auto due = d.host.next_due()) wait_us = std::clamp<int64_t>((*due - now).us(), 0, wait_us);
    if (lcm_handle_timeout(d.lcm, static_cast<int>((wait_us + 999) / 1000)) < 0) {
      return Error{"--url " + d.o.url + ": receiving failed"};
    }
  }
  Status finished = d.host.finish();  // after a failure, finish() writes nothing
  LiveReport report;
  report.received = d.host.deliveries();
  report.outputs = d.host.outputs();
  report.wall_s = running.seconds();
  report.modules = d.host.reports();
  Status closed = d.host.close();
  if (!d.failure.ok()) return Error{d.failure.message()};
  if (!d.host.failure().ok()) return Error{d.host.failure().message()};
  if (!finished.ok()) return finished.error();
  if (!closed.ok()) return closed.error();
  return report;
}

}  // namespace driftlab::runtime
