// A correction of one stream's clock, as the timing diagnosis proposes it and the replayer applies it.
#pragma once

#include <cstdint>
#include <map>
#include <string>

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

}  // namespace driftlab
