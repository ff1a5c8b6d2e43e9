#include "runtime/live_publisher.h"

#include <lcm/lcm.h>

#include <thread>

namespace driftlab::runtime {

Result<std::unique_ptr<LivePublisher>> LivePublisher::open(const std::string& url, double rate,
                                                           const std::string& option) {
  lcm_t* lcm = lcm_create(url.c_str());
  if (lcm == nullptr) return Error{option + " " + url + ": cannot open the LCM URL"};
  return std::unique_ptr<LivePublisher>(new LivePublisher(lcm, rate));
}

LivePublisher::~LivePublisher() { lcm_destroy(lcm_); }

void LivePublisher::publish(std::string_view channel, Time time, std::span<const uint8_t> bytes) {
  if (!first_) {
    first_ = time;
    start_ = std::chrono::steady_clock::now();
  }
  if (rate_ > 0) {
    const auto due =
        start_ + std::chrono::microseconds(static_cast<int64_t>(static_cast<double>(time.us_past(*first_)) / rate_));
    std::this_thread::sleep_until(due);
  }
  channel_.assign(channel);
  lcm_publish(lcm_, channel_.c_str(), bytes.data(), static_cast<unsigned int>(bytes.size()));
}

}  // namespace driftlab::runtime
