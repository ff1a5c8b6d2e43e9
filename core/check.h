// Broken invariants: what a caller inside driftlab promised and did not keep (a bug, never bad input, which gets an
// Error). The program says what failed and where, then aborts, so a core dump and the line to start from go together.
// Thread-safety: the message is one write to stderr.
#pragma once

#include <cstdio>
#include <cstdlib>

namespace driftlab {

/// Prints "driftlab: internal error at FILE:LINE: WHAT" and aborts.
[[noreturn]] inline void internal_error(const char* file, int line, const char* what) {
  std::fprintf(stderr, "driftlab: internal error at %s:%d: %s\n", file, line, what);
  std::abort();
}

}  // namespace driftlab

/// Aborts with the condition and the reason when `cond` is false: DRIFTLAB_CHECK(period > 0, "modules validate rates").
#define DRIFTLAB_CHECK(cond, why) \
  ((cond) ? static_cast<void>(0) : ::driftlab::internal_error(__FILE__, __LINE__, "failed " #cond ": " why))
