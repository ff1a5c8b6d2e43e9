#include "core/wall_clock.h"

#include <cstdio>
#include <ctime>

namespace driftlab {

Time SystemWallClock::now() const {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return Time::from_us(static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000);
}

std::string format_utime(int64_t utime) {
  constexpr int64_t kYear2000 = 946684800LL * 1000000;
  char buf[64];
  if (utime < kYear2000) {
    std::snprintf(buf, sizeof(buf), "%.6f s", Time::from_us(utime).seconds());
    return buf;
  }
  const time_t secs = static_cast<time_t>(utime / 1000000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%d %H:%M:%S", &tm);
  std::snprintf(buf, sizeof(buf), "%s.%06lld UTC", date, static_cast<long long>(utime % 1000000));
  return buf;
}

}  // namespace driftlab
