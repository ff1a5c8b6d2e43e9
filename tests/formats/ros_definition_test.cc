// formats/ros_definition: hostile message definitions (issue 31). A definition chaining 250,000 types overflowed
// the call stack when it was checked for cycles; 90,000 types in packages of their own took quadratic time to
// resolve. Both are refused or resolved quickly, with one line.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "formats/ros_definition.h"

namespace driftlab::formats {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

TEST(HostileDefinition, AChainOf250kTypesIsRefusedWithoutRecursion) {
  constexpr int kTypes = 250'000;
  std::string text = "pkg/T1 next\n";
  for (int i = 1; i < kTypes; ++i) {
    text += "================================================================================\nMSG: pkg/T" +
            std::to_string(i) + "\n" + (i + 1 < kTypes ? "T" + std::to_string(i + 1) + " next\n" : "int32 x\n");
  }
  for (const auto ser : {Serialization::kRos1, Serialization::kCdr}) {
    const auto t0 = std::chrono::steady_clock::now();
    auto d = RosDefinition::parse("pkg/T0", text, ser);
    ASSERT_FALSE(d.ok());
    EXPECT_EQ(d.error().message,
              "type pkg/T0 nests types more than 64 deep (through pkg/T65), more than a message is read through");
    EXPECT_LT(seconds_since(t0), 10);
  }
  // 64 deep is read.
  std::string ok = "pkg/T1 next\n";
  for (int i = 1; i <= 64; ++i) {
    ok +=
        "===\nMSG: pkg/T" + std::to_string(i) + "\n" + (i < 64 ? "T" + std::to_string(i + 1) + " next\n" : "int32 x\n");
  }
  EXPECT_TRUE(RosDefinition::parse("pkg/T0", ok, Serialization::kCdr).ok());
  // A type reached first near the top and then again deep down is counted at its deepest.
  std::string diamond = "pkg/T1 next\npkg/Deep shallow\n";
  for (int i = 1; i <= 60; ++i)
    diamond +=
        "===\nMSG: pkg/T" + std::to_string(i) + "\n" + (i < 60 ? "T" + std::to_string(i + 1) : "Deep") + " next\n";
  diamond += "===\nMSG: pkg/Deep\nD1 a\n";
  for (int i = 1; i <= 10; ++i)
    diamond +=
        "===\nMSG: pkg/D" + std::to_string(i) + "\n" + (i < 10 ? "D" + std::to_string(i + 1) + " a\n" : "int32 x\n");
  auto d = RosDefinition::parse("pkg/T0", diamond, Serialization::kCdr);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("more than 64 deep"), std::string::npos) << d.error().message;
}

TEST(HostileDefinition, NinetyThousandTypesInTheirOwnPackagesResolveInLinearTime) {
  constexpr int kTypes = 90'000;
  std::string text;
  for (int i = 0; i < kTypes; ++i) text += "T" + std::to_string(i) + " f" + std::to_string(i) + "\n";
  for (int i = 0; i < kTypes; ++i) {
    text += "===\nMSG: p" + std::to_string(i) + "/T" + std::to_string(i) + "\nint32 x\n";
  }
  const auto t0 = std::chrono::steady_clock::now();
  auto d = RosDefinition::parse("root/Root", text, Serialization::kCdr);
  ASSERT_TRUE(d.ok()) << d.error().message;
  EXPECT_EQ(d->types().size(), static_cast<size_t>(kTypes) + 1);
  EXPECT_EQ(d->types()[0].fields.back().type, "p89999/T89999");
  EXPECT_LT(seconds_since(t0), 5);
  // A short name two packages share is still ambiguous.
  auto amb =
      RosDefinition::parse("root/Root", "T a\n===\nMSG: p/T\nint32 x\n===\nMSG: q/T\nint32 y\n", Serialization::kCdr);
  ASSERT_FALSE(amb.ok());
  EXPECT_EQ(amb.error().message, "line 1: type T is ambiguous");
}

}  // namespace
}  // namespace driftlab::formats
