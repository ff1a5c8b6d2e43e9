// A correction of one stream's clock, as the timing diagnosis proposes it and the replayer applies it.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "core/time.h"

namespace driftlab {

/// The source clock ran ahead of the log's clock by offset_s + drift_ppm * 1e-6 * (stamp - reference_utime); a
/// correction subtracts that from the stream's header stamps.
struct ClockCorrection {
  double offset_s = 0;
  double drift_ppm = 0;
  int64_t reference_utime = 0;  ///< 0: the first event of the replay
};

/// Per channel (as named in the input logs).
using ClockCorrections = std::map<std::string, ClockCorrection>;

/// A stamp [us] corrected: less the offset and the drift since the reference (`base_utime` when the reference is 0).
inline int64_t corrected_stamp(const ClockCorrection& c, int64_t stamp_utime, int64_t base_utime) {
  const int64_t ref = c.reference_utime != 0 ? c.reference_utime : base_utime;
  const double correction = c.offset_s + c.drift_ppm * 1e-6 * static_cast<double>(stamp_utime - ref) * 1e-6;
  return stamp_utime - Duration::from_seconds_rounded(correction).us();
}

}  // namespace driftlab
