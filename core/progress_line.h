// Progress on a terminal: a percentage line for a job that knows its size, and a stage's running time for one
// that does not. Both draw on stderr only when it is a terminal, so pipes and logs stay clean.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "core/wall_clock.h"

namespace driftlab {

/// A one-line progress indicator on stderr, drawn only when stderr is a terminal, at most 10 times a second.
class Progress {
 public:
  /// unit: what update() counts, shown as "done of total": bytes, or milliseconds shown as seconds.
  enum class Unit { kBytes, kMilliseconds };
  explicit Progress(std::string label, Unit unit = Unit::kBytes);
  ~Progress();
  void update(uint64_t done, uint64_t total);
  /// Clears the line, so what follows starts on a clean one.
  void finish();

 private:
  std::string label_;
  Unit unit_;
  bool enabled_;
  bool drawn_ = false;
  Stopwatch running_, since_drawn_;
};

/// "reading the logs ... 4.2 s", redrawn twice a second on stderr while a stage runs, when stderr is a terminal.
class StageLine {
 public:
  explicit StageLine(std::string what);
  ~StageLine();
  StageLine(const StageLine&) = delete;
  StageLine& operator=(const StageLine&) = delete;
  /// What the line says from now on (the time keeps running).
  void set(std::string what);
  /// Stops the line and clears it.
  void finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace driftlab
