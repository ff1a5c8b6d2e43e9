// GMapping's corrected trajectory of a CARMEN run at the raw scans' stamps, as a TUM file, for scripts/bench
// slam2d (ATE against it): carmen_reference_tum RAW.lcm CORRECTED.lcm OUT.tum (both logs from `driftlab import`).
#include <cstdio>

#include "analyzers/trajectory_io.h"
#include "tests/carmen_reference.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: carmen_reference_tum RAW.lcm CORRECTED.lcm OUT.tum\n");
    return 2;
  }
  auto t = driftlab::test::corrected_at_raw_stamps(argv[1], argv[2]);
  if (!t) {
    std::fprintf(stderr, "carmen_reference_tum: %s\n", t.error().message.c_str());
    return 2;
  }
  if (auto s = driftlab::analyzers::write_tum(argv[3], *t); !s) {
    std::fprintf(stderr, "carmen_reference_tum: %s\n", s.message().c_str());
    return 1;
  }
  return 0;
}
