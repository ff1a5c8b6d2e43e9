// driftlab recover's command line: its exit codes, and nothing left behind when it fails. What it recovers is
// tested on the library (tests/recorder/recover_test.cc).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kData = DRIFTLAB_TEST_DATA;

test::CmdResult driftlab(const std::string& args) { return test::run_capture("timeout 60 " + kDriftlab + " " + args); }

TEST(Recover, WhatIsNoLogOrCannotBeWrittenLeavesNothing) {
  test::TempDir dir;
  auto r = driftlab("recover " + kData + "/not_a_log.txt -o " + dir.file("x.lcm"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not_a_log.txt: not an LCM event log"), std::string::npos) << r.err;
  r = driftlab("recover " + kData + "/sample.lcm -o " + dir.file("missing/x.lcm"));
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

}  // namespace
}  // namespace driftlab
