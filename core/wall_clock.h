// The wall clock, pushed in from outside. What needs the time of day (the recorder stamping what the kernel did
// not, the live runner moving its module host, a sweep point noting when it started) takes a `const WallClock&`
// from its caller; only programs (apps/) make the system's, so every component can be run on a clock a test sets.
// Replay, the simulator and the modules never see one: their time is the log's (runtime/bus.h).
// How long something took is another matter, measured on the steady clock by a Stopwatch (it never steps with the
// date); such a figure is reported, never written into a replay's output unless asked (--timing).
// Thread-safety: now() may be called from any thread; a Stopwatch is a value.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "core/time.h"

namespace driftlab {

class WallClock {
 public:
  virtual ~WallClock() = default;
  /// The time of day [us since the Unix epoch, UTC].
  virtual Time now() const = 0;
};

/// The system's wall clock (CLOCK_REALTIME): for programs to hand to what they run.
class SystemWallClock final : public WallClock {
 public:
  Time now() const override;
};

/// A log timestamp [us] as "2026-11-22 02:20:22.123456 UTC", or as seconds when it is not a plausible epoch time.
std::string format_utime(int64_t utime);

/// Time elapsed on the steady clock since it was made or last restarted.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void restart() { start_ = std::chrono::steady_clock::now(); }
  /// [s]
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace driftlab
