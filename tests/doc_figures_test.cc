// tests/doc_figures.h: a docs page's table row found, and its figures (and a sentence's) compared as printed.
#include "tests/doc_figures.h"

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/test_util.h"

namespace driftlab {
namespace {

// EXPECT_NONFATAL_FAILURE's statement may not name locals: the page lives here.
std::string page;  // NOLINT(runtime/string)

class DocFigures : public ::testing::Test {
 protected:
  void SetUp() override {
    page = dir_.file("page.md");
    std::ofstream(page)
        << "# A page\n\n| log | mean |\n|---|---:|\n| Intel | 0.090 m |\n\n"
        << "### The table\n\nIts words.\n\n"
        << "| log | scans | mean | max | closures (chi2, undone) |\n|---|---:|---:|---:|---:|\n"
        << "| Intel (bag) | 13,631 | 0.031 m | **118 m** | 563 (11, 1) |\n"
        << "| ACES | 7,374 | 0.048 m | 0.78 m | 76 (0, 0) |\n\n"
        << "| Later | 1 |\n\n"
        << "- The SLAM (a pose graph): 3.1\n  and 4.8 cm on Intel and ACES, where `icp-slam` has 2.96 m\n"
        << "  and 7.8 cm; its map builder 12 too.\n";
  }
  test::TempDir dir_;
};

TEST_F(DocFigures, FindsTheRowOfTheFirstTableAfterTheLine) {
  const auto row = test::doc_table_row(page, "### The table", "Intel (bag)");
  ASSERT_EQ(row.size(), 5u);
  EXPECT_EQ(row[1], "13,631");
  EXPECT_EQ(row[4], "563 (11, 1)");
  // The first table on the page has an Intel row too, and a later table a row the first after the line lacks.
  EXPECT_EQ(test::doc_table_row(page, "# A page", "Intel")[1], "0.090 m");
  EXPECT_TRUE(test::doc_table_row(page, "### The table", "Intel").empty());
  EXPECT_TRUE(test::doc_table_row(page, "### The table", "Later").empty());
  EXPECT_TRUE(test::doc_table_row(page, "### No such table", "ACES").empty());
}

TEST_F(DocFigures, TakesEachFigureAsPrinted) {
  // A decimal within one unit of its last digit, a whole number rounded, a count exactly.
  test::expect_doc_figures(page, "### The table", "Intel (bag)", 1, {13631});
  test::expect_doc_figures(page, "### The table", "Intel (bag)", 2, {0.0309});
  test::expect_doc_figures(page, "### The table", "Intel (bag)", 2, {0.0319});
  test::expect_doc_figures(page, "### The table", "Intel (bag)", 3, {117.99});
  test::expect_doc_figures(page, "### The table", "Intel (bag)", 4, {563, 11, 1});
}

TEST_F(DocFigures, FailsWhereTheCodeMovedAFigure) {
  EXPECT_NONFATAL_FAILURE(test::expect_doc_figures(page, "### The table", "Intel (bag)", 2, {0.0332}),
                          "column 2 (\"0.031 m\") says 0.031");
  EXPECT_NONFATAL_FAILURE(test::expect_doc_figures(page, "### The table", "Intel (bag)", 4, {562, 11, 1}),
                          "column 4 (\"563 (11, 1)\") says 563");
  EXPECT_NONFATAL_FAILURE(test::expect_doc_figures(page, "### The table", "Intel (bag)", 3, {117.4}),
                          "column 3 (\"**118 m**\") says 118");
  EXPECT_FATAL_FAILURE(test::expect_doc_figures(page, "### The table", "Intel (bag)", 4, {563}), "563 (11, 1)");
  EXPECT_FATAL_FAILURE(test::expect_doc_figures(page, "### The table", "MIT CSAIL", 1, {1988}), "no such row");
}

TEST_F(DocFigures, TakesTheFiguresOfASentenceAcrossItsLines) {
  EXPECT_EQ(test::doc_text_between(page, "(a pose graph):", "; its map"),
            " 3.1   and 4.8 cm on Intel and ACES, where `icp-slam` has 2.96 m   and 7.8 cm");
  test::expect_doc_text_figures(page, "(a pose graph):", "; its map", {0.0305 * 100, 4.84, 2.955, 7.8});
  // A figure another test checks is NaN here: Intel's test checks the first and third, ACES's the others.
  test::expect_doc_text_figures(page, "(a pose graph):", "; its map", {NAN, 4.8, NAN, 7.75});
  EXPECT_NONFATAL_FAILURE(test::expect_doc_text_figures(page, "(a pose graph):", "; its map", {3.1, 4.8, 2.98, 7.8}),
                          "figure 3 says 2.96");
  EXPECT_FATAL_FAILURE(test::expect_doc_text_figures(page, "(a pose graph):", "; its map", {3.1, 4.8, 2.96}), "7.8 cm");
  EXPECT_FATAL_FAILURE(test::expect_doc_text_figures(page, "(a pose graph):", "no such end", {3.1}), "no such text");
  EXPECT_TRUE(test::doc_text_between(page, "no such start", "; its map").empty());
}

}  // namespace
}  // namespace driftlab
