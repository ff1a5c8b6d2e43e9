// core/closest_name.h: the guess behind "did you mean" on the command line and in config files.
#include "core/closest_name.h"

#include <gtest/gtest.h>

namespace driftlab {
namespace {

TEST(EditDistance, CountsInsertionsDeletionsReplacementsAndSwaps) {
  EXPECT_EQ(edit_distance("", ""), 0u);
  EXPECT_EQ(edit_distance("rate", "rate"), 0u);
  EXPECT_EQ(edit_distance("rat", "rate"), 1u);           // an insertion
  EXPECT_EQ(edit_distance("ratee", "rate"), 1u);         // a deletion
  EXPECT_EQ(edit_distance("rote", "rate"), 1u);          // a replacement
  EXPECT_EQ(edit_distance("daignose", "diagnose"), 1u);  // two neighbours swapped: one edit, not two
  EXPECT_EQ(edit_distance("abc", ""), 3u);
}

TEST(ClosestName, GuessesAFewEditsAwayOrAUniquePrefixAndNothingElse) {
  const std::vector<std::string> commands = {"diagnose", "demo", "replay", "record", "recover", "report"};
  EXPECT_EQ(closest_name("daignose", commands), "diagnose");
  EXPECT_EQ(closest_name("recod", commands), "record");
  // Up to one edit in three characters (at least two): "raport" is one from "report"; "xyzzy" is near nothing.
  EXPECT_EQ(closest_name("raport", commands), "report");
  EXPECT_EQ(closest_name("xyzzy", commands), "");
  // A unique name the word begins (three characters or more) is guessed; an ambiguous one ("re") is not.
  EXPECT_EQ(closest_name("diag", commands), "diagnose");
  EXPECT_EQ(closest_name("re", commands), "");
  EXPECT_EQ(closest_name("voxle", {"voxel", "map_voxel", "method"}), "voxel");
}

}  // namespace
}  // namespace driftlab
