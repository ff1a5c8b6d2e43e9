// The largest single allocation made by operator new in a stretch of a test: this test binary replaces the global
// operator new (largest_allocation.cc) with one that counts, so a test can tell that a decoder never allocated for a
// count a message only claims. Not for nesting; thread-safe counting.
#pragma once

#include <cstddef>

namespace driftlab::test {

/// Starts counting from zero.
void start_counting_allocations();
/// Stops counting; the largest single allocation since start_counting_allocations() [bytes].
std::size_t largest_allocation();

}  // namespace driftlab::test
