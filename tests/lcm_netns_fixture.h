// A test fixture for tests that talk LCM over udpm: skipped unless run by tests/netns_run.sh (a private network
// namespace), with an LCM instance and a scratch folder.
#pragma once

#include <gtest/gtest.h>
#include <lcm/lcm.h>

#include <cstdlib>
#include <ostream>
#include <string>
#include <vector>

#include "tests/test_util.h"

namespace driftlab::test {

inline constexpr const char* kLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// A message as sent or recorded.
struct LcmMessage {
  std::string channel;
  std::vector<uint8_t> data;
  bool operator==(const LcmMessage&) const = default;
  friend void PrintTo(const LcmMessage& m, std::ostream* os) { *os << m.channel << " (" << m.data.size() << " bytes)"; }
};

class LcmNetnsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (std::getenv("DRIFTLAB_IN_NETNS") == nullptr) GTEST_SKIP() << "run through tests/netns_run.sh";
    lcm_ = lcm_create(kLcmUrl);
    ASSERT_NE(lcm_, nullptr);
  }
  void TearDown() override {
    if (lcm_ != nullptr) lcm_destroy(lcm_);
  }
  lcm_t* lcm_ = nullptr;
  TempDir dir_;
};

}  // namespace driftlab::test
