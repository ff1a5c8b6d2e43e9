// Runs the same modules live: on an LCM bus (udpm), with the wall clock as their clock (the caller's WallClock
// moves the host between messages; LCM stamps each message's arrival). The replay's twin, on the
// same host (module_host.h): what a module does here it does there, message for message; here it meets real
// timing. Every message on a channel a module subscribed to goes to the host, which routes it; what the
// modules publish goes on the bus (and so back to them) and into an output log, with their statistics
// (processing time measured, as nothing needs to repeat).
// Thread-safety: run() handles every message and timer on its own thread; modules need no locking.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "core/result.h"
#include "core/wall_clock.h"
#include "runtime/bus.h"
#include "runtime/module_host.h"

namespace driftlab::runtime {

struct LiveOptions {
  std::string url;              ///< LCM URL, e.g. udpm://239.255.76.67:7667?ttl=0
  std::string out;              ///< log of the module outputs and statistics; empty: none
  double duration_s = 0;        ///< stop after this long [s]; 0: until stopped
  double stats_period_s = 1.0;  ///< [s]
  std::string stats_channel = "MODULE_STATS";
};

struct LiveReport {
  int64_t received = 0;  ///< messages handled (all modules)
  int64_t outputs = 0;   ///< messages the modules published
  double wall_s = 0;
  std::vector<ModuleReport> modules;
};

class LiveRunner {
 public:
  /// `clock` (borrowed: it must outlive the runner) is read on run()'s thread between messages.
  LiveRunner(LiveOptions options, const WallClock& clock);
  ~LiveRunner();
  void add_module(std::unique_ptr<Module> module);
  /// Opens the LCM URL and the output log and starts the modules; errors name the URL, file or module.
  Status open();
  /// Handles messages and timers until the duration has passed or *stop is set, then finishes the modules.
  Result<LiveReport> run(const std::atomic<bool>* stop = nullptr);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::runtime
