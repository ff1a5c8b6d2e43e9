// A figure a docs page shows in a Markdown table, checked against what the code gives now: a test that measures it
// calls expect_doc_figures, and when the code moves the figure the test fails and names the page, the table, the row
// and the column to regenerate (docs/architecture.md, "Docs that run", does the same for console blocks).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace driftlab::test {

/// The cells of a row of the first Markdown table after the first line of `page` (relative to the repository, or
/// an absolute path) that holds `after` (a heading or the words that open a paragraph): the row whose first cell is
/// `label`, each cell trimmed. Empty when the page, the line, the table or the row is not there.
inline std::vector<std::string> doc_table_row(const std::string& page, const std::string& after,
                                              const std::string& label) {
  std::ifstream in(page.rfind('/', 0) == 0 ? page : std::string(DRIFTLAB_SOURCE_DIR) + "/" + page);
  std::string line;
  while (std::getline(in, line) && line.find(after) == std::string::npos) {
  }
  bool in_table = false;
  while (std::getline(in, line)) {
    if (line.rfind('|', 0) != 0) {
      if (in_table) break;  // the table ended without the row
      continue;
    }
    in_table = true;
    std::vector<std::string> cells;
    std::stringstream row(line.substr(1));
    std::string cell;
    while (std::getline(row, cell, '|')) {
      const size_t first = cell.find_first_not_of(' '), last = cell.find_last_not_of(' ');
      cells.push_back(first == std::string::npos ? "" : cell.substr(first, last - first + 1));
    }
    if (!cells.empty() && cells[0] == label) return cells;
  }
  return {};
}

/// Expects the numbers in one cell of such a row (in their order: "563 (11, 1)" holds 563, 11 and 1; "13,631" is
/// one) to be `values` as printed: a decimal within one unit of its last digit (0.031 takes 0.030 to 0.032), as the doc
/// runner compares a console block's numbers; a whole number rounded (118 takes 117.99; a count of 563 only 563).
inline void expect_doc_figures(const std::string& page, const std::string& after, const std::string& label,
                               size_t column, const std::vector<double>& values) {
  const std::string where = page + ", the table after \"" + after + "\", row \"" + label + "\"";
  const auto row = doc_table_row(page, after, label);
  ASSERT_GT(row.size(), column) << where << ": no such row or column " << column;
  static const std::regex number(R"([-+]?\d{1,3}(?:,\d{3})+(?:\.\d+)?|[-+]?\d+(?:\.\d+)?)");
  const std::string& cell = row[column];
  std::vector<std::string> printed;
  for (auto it = std::sregex_iterator(cell.begin(), cell.end(), number); it != std::sregex_iterator(); ++it) {
    printed.push_back(it->str());
  }
  ASSERT_EQ(printed.size(), values.size()) << where << ", column " << column << ": \"" << cell << "\"";
  for (size_t i = 0; i < values.size(); ++i) {
    std::string digits = printed[i];
    digits.erase(std::remove(digits.begin(), digits.end(), ','), digits.end());
    const size_t point = digits.find('.');
    const double unit =
        point == std::string::npos ? 0.5 : std::pow(10.0, -static_cast<double>(digits.size() - point - 1));
    EXPECT_LE(std::abs(std::strtod(digits.c_str(), nullptr) - values[i]), unit * (1 + 1e-9))
        << where << ", column " << column << " says " << printed[i] << " (\"" << cell << "\"); the code gives "
        << values[i] << " now: run the table's commands again and put their figures in";
  }
}

}  // namespace driftlab::test
