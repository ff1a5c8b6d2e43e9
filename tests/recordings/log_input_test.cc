// recordings/log_input.h: another tool's recording read through its cached conversion, and a conversion's problem
// lines (the first 20 printed, the rest counted once).
#include "recordings/log_input.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "tests/test_util.h"

namespace driftlab::recordings {
namespace {

TEST(ProblemLines, TheFirstTwentyArePrintedAndTheRestCounted) {
  testing::internal::CaptureStderr();
  ProblemLines problems("talker.db3");
  for (int i = 0; i < 23; ++i) problems("talker.db3: /chatter: message " + std::to_string(i) + " cut short");
  problems.finish();
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(problems.count(), 23);
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 21) << err;
  EXPECT_NE(err.find("driftlab: talker.db3: /chatter: message 19 cut short\n"), std::string::npos);
  EXPECT_EQ(err.find("message 20 cut short"), std::string::npos);
  EXPECT_EQ(err.substr(err.size() - 38), "driftlab: talker.db3: 3 more problems\n");

  testing::internal::CaptureStderr();
  ProblemLines few("a.bag");
  few("a.bag: one");
  few.finish();
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "driftlab: a.bag: one\n");  // nothing more to say
}

// A ROS 2 bag is converted once; the second run reads the conversion kept beside it.
TEST(LogFor, ABagIsConvertedOnceAndItsConversionReused) {
  const std::string shared = std::string(DRIFTLAB_SHARED_DATA) + "/bags/mcap_talker_talker.mcap";
  if (!std::filesystem::exists(shared)) GTEST_SKIP() << shared << " absent (../shared/data)";
  test::TempDir dir;
  const std::string bag = dir.file("talker.mcap");
  std::filesystem::copy_file(shared, bag);
  testing::internal::CaptureStderr();
  auto first = log_for(bag);
  const std::string converting = testing::internal::GetCapturedStderr();
  ASSERT_TRUE(first) << first.error().message;
  EXPECT_NE(converting.find("converting it to " + *first), std::string::npos) << converting;
  EXPECT_TRUE(std::filesystem::exists(*first));
  testing::internal::CaptureStderr();
  auto again = log_for(bag);
  const std::string reused = testing::internal::GetCapturedStderr();
  ASSERT_TRUE(again);
  EXPECT_EQ(*again, *first);
  EXPECT_EQ(reused.find("converting"), std::string::npos) << reused;
  // Our own log is its own input: nothing converted.
  auto own = log_for(std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm");
  ASSERT_TRUE(own);
  EXPECT_EQ(*own, std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm");
}

}  // namespace
}  // namespace driftlab::recordings
