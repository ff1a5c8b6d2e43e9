// Tests for runtime/module_input.h: the inputs a module drops for their numbers are counted, the first one named.
#include "runtime/module_input.h"

#include <gtest/gtest.h>

#include <cmath>

#include "driftlab/odometry_t.hpp"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using test::encode;

TEST(NonFinite, ModulesCountTheDroppedAndNameTheFirst) {
  NonFiniteInputs inputs;
  driftlab::odometry_t o{};
  o.header = {0, 1, "odom"};
  const auto good = encode(o);
  o.angular_velocity.z = NAN;
  const auto nan = encode(o);
  EXPECT_TRUE(inputs.finite({"ODOM", Time::from_us(1), good}));
  EXPECT_EQ(inputs.warning("estimator"), std::nullopt);
  EXPECT_FALSE(inputs.finite({"ODOM", Time::from_us(2), nan}));
  inputs.count("SCAN", "angle_increment * (nranges - 1) = inf");
  EXPECT_EQ(inputs.dropped(), 2);
  EXPECT_EQ(
      inputs.warning("estimator"),
      "estimator: 2 inputs with NaN, infinite or out-of-range numbers dropped (first: ODOM: angular_velocity.z = nan)");
}

}  // namespace
}  // namespace driftlab
