// core/install_layout.h in the build tree: the same lookup as in an install tree (tests/install_test.sh runs that
// one), here through build/share/driftlab's links to sim/'s folders.
#include "core/install_layout.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace driftlab {
namespace {

namespace fs = std::filesystem;

TEST(InstallLayout, SelfIsThisTestProgramInTheBuildTree) {
  const fs::path self = self_executable();
  ASSERT_FALSE(self.empty());
  EXPECT_TRUE(fs::equivalent(self.parent_path(), DRIFTLAB_BIN_DIR));
}

TEST(InstallLayout, DataIsFoundBesideTheProgramsFolder) {
  EXPECT_TRUE(fs::equivalent(data_dir(), fs::path(DRIFTLAB_BIN_DIR) / ".." / "share" / "driftlab"));
  // The build tree's data folder leads to sim/'s data, and a scenario's relative paths resolve from there.
  EXPECT_TRUE(fs::equivalent(data_path("scenarios/indoor.yaml"),
                             fs::path(DRIFTLAB_SOURCE_DIR) / "sim" / "scenarios" / "indoor.yaml"));
  EXPECT_TRUE(fs::is_regular_file(data_path("scenarios") / ".." / "worlds" / "building.yaml"));
  EXPECT_TRUE(fs::is_regular_file(data_path("robots/diffbot.urdf")));
}

TEST(InstallLayout, SiblingProgramsAreExecutablesBesideThisOne) {
  EXPECT_EQ(sibling_program(self_executable().filename().string()), self_executable());
  EXPECT_TRUE(sibling_program("no-such-driftlab-program").empty());
  EXPECT_TRUE(sibling_program("..").empty());  // a folder is not a program
  EXPECT_EQ(sibling_library(self_executable().filename().string()), self_executable());
  EXPECT_TRUE(sibling_library("no-such-driftlab-library.so").empty());
  EXPECT_TRUE(sibling_library("..").empty());
}

}  // namespace
}  // namespace driftlab
