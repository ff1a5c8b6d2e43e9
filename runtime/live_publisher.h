// Messages published on LCM as a log has them, paced against the wall clock (`driftlab replay --publish`,
// `driftlab sim --live`).
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "core/result.h"
#include "core/time.h"

struct _lcm_t;  // NOLINT(bugprone-reserved-identifier): LCM's own name for lcm_t, declared to keep lcm.h out

namespace driftlab::runtime {

/// Publishes messages on LCM, paced against the wall clock at `rate` x the messages' own time (0: as fast as
/// possible), as lcm-logplayer does.
class LivePublisher {
 public:
  /// Errors name the URL and the option it came from.
  static Result<std::unique_ptr<LivePublisher>> open(const std::string& url, double rate, const std::string& option);
  ~LivePublisher();
  /// Sleeps until the message is due, then publishes it.
  void publish(std::string_view channel, Time time, std::span<const uint8_t> bytes);

 private:
  LivePublisher(_lcm_t* lcm, double rate) : lcm_(lcm), rate_(rate) {}
  _lcm_t* lcm_;
  double rate_;
  std::optional<Time> first_;
  std::chrono::steady_clock::time_point start_;
  std::string channel_;
};

}  // namespace driftlab::runtime
