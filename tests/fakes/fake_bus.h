// The fakes module tests use: a log kept in memory, and the bus a module under test sees, which is the real module
// host (runtime/module_host.h) on its virtual clock, fed by the test. A module tested here meets exactly the
// routing, timers, now(), validation and exception handling it meets on replay.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/result.h"
#include "core/time.h"
#include "runtime/bus.h"
#include "runtime/module_host.h"
#include "tests/test_util.h"

namespace driftlab::test {

/// A log in memory: the events a host records, in order (event numbers from 0, offsets 0).
class MemoryLog final : public runtime::LogSink {
 public:
  explicit MemoryLog(std::vector<OwnedEvent>& into) : into_(into) {}
  Status write(int64_t utime, std::string_view channel, std::span<const uint8_t> data) override;
  Status close() override { return {}; }

 private:
  std::vector<OwnedEvent>& into_;
};

/// Modules under test on the replay host, virtual clock: the test delivers messages (or plays a log) at their
/// times; timers tick at whole multiples of their period before the first message at or after the tick; what the
/// modules publish reaches the other modules at the same instant and is kept, with the statistics, in memory.
/// The modules stay the test's: it can ask them for their counters afterwards.
class FakeBus {
 public:
  struct Options {
    std::string artifact_prefix;  ///< where modules may write files; empty: none
    double stats_period_s = 0;    ///< module statistics on MODULE_STATS [s]; 0: once, at finish()
  };
  FakeBus() : FakeBus(Options{}) {}
  explicit FakeBus(const Options& options);
  ~FakeBus();

  /// Hosts a module (borrowed: it must outlive the bus). Before start() only.
  void add(Module& module);
  /// Starts the modules; their start() errors as is.
  Status start();
  /// Moves the clock to t, firing the timer ticks due.
  Status advance(Time t);
  /// Delivers encoded bytes on a channel at time t.
  Status deliver(const std::string& channel, std::span<const uint8_t> data, Time t);
  template <typename T>
  Status deliver_message(const std::string& channel, const T& message, Time t) {
    return deliver(channel, encode(message), t);
  }
  /// Delivers a log's events on channels fully matching `channels` (empty: all) at their log times, each through
  /// `rewrite` first when given (to make a message wrong on purpose).
  using Rewrite = std::function<void(const std::string& channel, std::vector<uint8_t>& data)>;
  Status play(const std::string& log, const std::string& channels = {}, const Rewrite& rewrite = {});
  /// Calls the modules' finish() and writes the last statistics.
  Status finish();
  /// start(), play(), finish().
  Status run(const std::string& log, const std::string& channels = {}, const Rewrite& rewrite = {});

  Time now() const { return host_->now(); }
  /// Everything recorded: the modules' outputs and their statistics (MODULE_STATS), at the time they were made.
  const std::vector<OwnedEvent>& recorded() const { return recorded_; }
  /// What the modules published on a channel (".*": every output, statistics left out).
  std::vector<OwnedEvent> published(const std::string& channel_regex = ".*") const;
  std::vector<runtime::ModuleReport> reports() const { return host_->reports(); }

 private:
  std::vector<OwnedEvent> recorded_;
  std::unique_ptr<runtime::ModuleHost> host_;
};

}  // namespace driftlab::test
