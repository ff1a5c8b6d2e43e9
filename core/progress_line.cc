#include "core/progress_line.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <thread>

#include "core/number_text.h"

namespace driftlab {

Progress::Progress(std::string label, Unit unit)
    : label_(std::move(label)), unit_(unit), enabled_(isatty(STDERR_FILENO) == 1) {}

struct StageLine::State {
  std::mutex mutex;
  std::string what;
  std::atomic<bool> done{false};
  std::thread ticker;
};

StageLine::StageLine(std::string what) : state_(std::make_unique<State>()) {
  state_->what = std::move(what);
  if (isatty(STDERR_FILENO) != 1) return;
  state_->ticker = std::thread([s = state_.get()] {
    const Stopwatch running;
    while (!s->done) {
      {
        std::lock_guard lock(s->mutex);
        std::fprintf(stderr, "\r\033[K%s ... %.1f s", s->what.c_str(), running.seconds());
      }
      std::fflush(stderr);
      for (int i = 0; i < 5 && !s->done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
}

StageLine::~StageLine() { finish(); }

void StageLine::set(std::string what) {
  std::lock_guard lock(state_->mutex);
  state_->what = std::move(what);
}

void StageLine::finish() {
  state_->done = true;
  if (state_->ticker.joinable()) {
    state_->ticker.join();
    std::fprintf(stderr, "\r\033[K");
  }
}

Progress::~Progress() { finish(); }

void Progress::finish() {
  if (drawn_) std::fprintf(stderr, "\r\033[K");
  drawn_ = false;
}

void Progress::update(uint64_t done, uint64_t total) {
  if (!enabled_) return;
  // Stay silent for quick jobs; then redraw at most every 100 ms.
  if (running_.seconds() < 1.0 || (drawn_ && since_drawn_.seconds() < 0.1)) return;
  since_drawn_.restart();
  drawn_ = true;
  const double pct = total > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total) : 0.0;
  if (unit_ == Unit::kBytes) {
    std::fprintf(stderr, "\r\033[K%s %5.1f%%  %s of %s", label_.c_str(), pct, human_bytes(done).c_str(),
                 human_bytes(total).c_str());
  } else {
    std::fprintf(stderr, "\r\033[K%s %5.1f%%  %.0f s of %.0f s", label_.c_str(), pct, static_cast<double>(done) * 1e-3,
                 static_cast<double>(total) * 1e-3);
  }
  std::fflush(stderr);
}

}  // namespace driftlab
