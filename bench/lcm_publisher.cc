// A paced LCM publisher for the recorder benchmark: N messages per second of a given size on one channel, each
// starting with its sequence number (uint64, little-endian), spaced evenly in time (busy-waiting between
// messages, as a sensor driver's timer would not drift).
//   lcm_publisher URL CHANNEL RATE_HZ SIZE_BYTES SECONDS
#include <lcm/lcm.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: lcm_publisher URL CHANNEL RATE_HZ SIZE_BYTES SECONDS\n");
    return 2;
  }
  lcm_t* lcm = lcm_create(argv[1]);
  if (lcm == nullptr) {
    std::fprintf(stderr, "lcm_publisher: cannot create LCM for %s\n", argv[1]);
    return 1;
  }
  const double rate = std::atof(argv[3]);
  const size_t size = std::max<size_t>(8, std::strtoull(argv[4], nullptr, 10));
  const double seconds = std::atof(argv[5]);
  const auto total = static_cast<uint64_t>(rate * seconds);
  std::vector<uint8_t> payload(size, 0xAB);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  for (uint64_t seq = 0; seq < total; ++seq) {
    const auto due = start + std::chrono::nanoseconds(static_cast<int64_t>(1e9 * static_cast<double>(seq) / rate));
    while (Clock::now() < due) {
    }
    std::memcpy(payload.data(), &seq, sizeof(seq));
    if (lcm_publish(lcm, argv[2], payload.data(), static_cast<unsigned>(payload.size())) != 0) {
      std::fprintf(stderr, "lcm_publisher: publish failed at message %llu\n", static_cast<unsigned long long>(seq));
      return 1;
    }
  }
  const double took = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("%llu %.3f\n", static_cast<unsigned long long>(total), took);
  lcm_destroy(lcm);
  return 0;
}
