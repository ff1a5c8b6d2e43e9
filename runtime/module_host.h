// The module host: what runs processing modules (SLAM, estimator, controller) behind the Bus, for replay, live and
// tests alike. It starts the modules with a bus each and the artifact prefix, routes messages to their
// subscriptions, runs their timers, counts what they do (ModuleTally: inputs, late, out of order, outputs,
// processing time) and publishes it as driftlab.module_stats_t, drops and counts malformed inputs
// (lcmtypes/validate.h) before any handler sees them, counts and skips a message a module throws on, and writes an
// output log atomically.
//
// Time is the host's, passed in, never read here: advance(t) moves it (monotonic: never back), deliver() hands an
// input over at it.
// A module's now() is the time of the message it handles; inside a timer it is the tick time. Two clocks differ
// only in how late ticks are fired: HostClock::kVirtual (replay, tests) fires every tick in turn, each at its own
// time, so a replay is deterministic; HostClock::kWall (live) fires a late timer once, at its latest due tick,
// rather than a burst of stale ones.
// Thread-safety: one thread drives a host; modules are called from it only and need no locking.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "core/result.h"
#include "core/string_hash.h"
#include "core/time.h"
#include "runtime/bus.h"

namespace driftlab::runtime {

/// What the host measured about one module, and what the module counted itself.
struct ModuleReport {
  std::string name;
  int64_t inputs = 0, late = 0, out_of_order = 0, dropped = 0, outputs = 0;
  double proc_mean_s = 0, proc_p95_s = 0, proc_max_s = 0;  ///< 0 unless processing time is measured
  int32_t queue_depth_max = 0;
  std::vector<std::string> warnings;
  std::vector<std::pair<std::string, double>> metrics;  ///< the module's own (ModuleCounters::metrics)
};

/// Where the host records events: the output log file (LogWriter), or memory in tests.
class LogSink {
 public:
  virtual ~LogSink() = default;
  /// Appends one event at utime [us]. Errors name the file.
  virtual Status write(int64_t utime, std::string_view channel, std::span<const uint8_t> data) = 0;
  /// Makes the log whole and visible (an atomic file is renamed into place). Idempotent.
  virtual Status close() = 0;
};

/// An atomic output log file: written beside `path` and renamed into place by close(). Errors name the file.
Result<std::unique_ptr<LogSink>> open_log_file(const std::string& path);

enum class HostClock {
  kVirtual,  ///< replay and tests: every timer tick fires, in time order, at its own time
  kWall,     ///< live: a timer that fell behind fires once, at its latest due tick
};

struct HostOptions {
  HostClock clock = HostClock::kVirtual;
  /// true: what a module publishes goes to the modules (in publication order, at the same instant, before the next
  /// input), to the log and to the outlet; false (live): to the log and the outlet, which brings it back as input.
  bool loopback = true;
  std::string out;              ///< the output log (atomic); without ".lcm", the modules' artifact prefix; empty: none
  bool timing = false;          ///< measure processing time (and the queue it implies); makes a replay vary
  double stats_period_s = 1.0;  ///< module statistics every this long of host time [s]; <= 0: only at the end
  std::string stats_channel = "MODULE_STATS";
};

/// Where what the modules publish (and their statistics) goes besides the output log: a live bus, a re-publisher.
using Outlet = std::function<void(const BusMessage&)>;

class ModuleHost {
 public:
  explicit ModuleHost(HostOptions options);
  ~ModuleHost();
  ModuleHost(const ModuleHost&) = delete;
  ModuleHost& operator=(const ModuleHost&) = delete;

  void add_module(std::unique_ptr<Module> module);
  void set_outlet(Outlet outlet) { outlet_ = std::move(outlet); }

  /// Starts the modules (they subscribe), then opens the output log: `log` when given (tests), else
  /// options.out. Errors ("module NAME: ...", the log's) leave no output behind. Once only: a second call
  /// returns what the first did.
  Status start(std::unique_ptr<LogSink> log = {});
  /// start() in its two steps, for a caller that acts on the subscriptions before the log appears (the live
  /// runner subscribes on LCM).
  Status start_modules();
  Status open_log(std::unique_ptr<LogSink> log = {});
  /// The channel regexes the modules subscribed to, in order.
  std::vector<std::string> subscriptions() const;

  /// Moves the host's time to t: fires the timer ticks due up to t (those at t too), then publishes the
  /// statistics when a period has passed. Time never goes back: an earlier t only fires nothing.
  Status advance(Time t);
  /// Hands one input, at the host's time, to the modules subscribed to its channel (a malformed one is counted
  /// for each and handed to none), then delivers what they publish (loopback).
  Status deliver(std::string_view channel, std::span<const uint8_t> data);
  /// Records an event at the host's time: to the output log when `log`, to the outlet when `outlet`.
  Status record(std::string_view channel, std::span<const uint8_t> data, bool log, bool outlet);
  /// Calls every module's finish() and publishes the last statistics.
  Status finish();
  /// Closes the output log (an atomic file appears now). Idempotent.
  Status close();

  Time now() const { return Time::from_us(now_); }
  /// The next instant the host has something to do on its own (a timer tick, statistics), if any.
  std::optional<Time> next_due() const;
  /// Inputs handed to modules (one per subscribed module, malformed ones included) and outputs they published.
  int64_t deliveries() const { return deliveries_; }
  int64_t outputs() const { return outputs_; }
  /// The first write failure of the output log; later writes are skipped.
  const Status& failure() const { return failure_; }
  std::vector<ModuleReport> reports() const;

 private:
  class HostBus;
  struct Route {
    HostBus* bus;
    size_t sub;
  };
  // Times inside are int64_t microseconds (Time::us()): the tick arithmetic checks for overflow on them.
  struct Timer {
    int64_t period;  ///< [us]
    int64_t next;    ///< [us] 0: not yet placed; INT64_MAX after the last tick int64_t holds
    std::function<void()> fn;
    HostBus* bus;  ///< whose timer
  };
  struct Pending {
    std::string channel;
    std::vector<uint8_t> data;
  };

  void publish(HostBus& from, std::string_view channel, std::span<const uint8_t> data);
  Status fire_timers(int64_t t);
  Status maybe_stats();
  Status publish_stats();
  void dispatch(std::string_view channel, std::span<const uint8_t> data);
  Status drain();
  Status write(std::string_view channel, std::span<const uint8_t> data);
  const std::vector<Route>& routes(std::string_view channel);

  HostOptions o_;
  std::string prefix_;
  std::vector<std::unique_ptr<Module>> modules_;
  std::vector<std::unique_ptr<HostBus>> buses_;
  std::unique_ptr<LogSink> log_;
  Outlet outlet_;
  std::unordered_map<std::string, std::vector<Route>, StringHash, std::equal_to<>> routes_;
  std::unordered_set<std::string, StringHash, std::equal_to<>> names_;  ///< interned channel names
  std::deque<Pending> pending_;
  std::deque<Timer> timers_;  ///< a deque: a timer may add timers while it runs
  int64_t now_ = std::numeric_limits<int64_t>::min();
  int64_t next_stats_ = 0;
  int64_t stats_seq_ = 0;
  int64_t deliveries_ = 0, outputs_ = 0;
  bool started_ = false;
  Status started_status_;  ///< what start() said, said again
  Status failure_;
};

}  // namespace driftlab::runtime
