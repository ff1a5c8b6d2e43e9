#include "analyzers/clock_corrections.h"

#include <cstdio>

namespace driftlab::analyzers {

ClockCorrections clock_corrections(const Diagnosis& d, std::vector<std::string>* notes) {
  ClockCorrections r;
  for (const auto& c : d.channels) {
    if (!c.clock_valid) continue;
    const bool ahead = clock_ahead(c.clock_offset_s);
    const bool drifts = clock_drifts(c.clock_drift_ppm);
    if (!ahead && !drifts) continue;
    const ClockCorrection k{ahead ? c.clock_offset_s : 0.0, drifts ? c.clock_drift_ppm : 0.0, d.start_utime};
    r[c.name] = k;
    if (notes != nullptr) {
      char buf[256];
      std::snprintf(buf, sizeof(buf), "restamp %s: %+.1f ms, %+.0f ppm (from the timing diagnosis of %s)",
                    c.name.c_str(), k.offset_s * 1e3, k.drift_ppm, d.log.c_str());
      notes->push_back(buf);
    }
  }
  return r;
}

}  // namespace driftlab::analyzers
