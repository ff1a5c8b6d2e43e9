#include "core/wall_clock.h"

#include <ctime>

namespace driftlab {

Time SystemWallClock::now() const {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return Time::from_us(static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000);
}

}  // namespace driftlab
