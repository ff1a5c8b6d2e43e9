// A figure a docs page shows in a Markdown table (or quotes in a sentence), checked against what the code gives now:
// a test that measures it calls expect_doc_figures (expect_doc_text_figures), and when the code moves the figure the
// test fails and names the page, the table, the row and the column to regenerate (docs/architecture.md, "Docs that
// run", does the same for console blocks).
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

/// The numbers of `text` in their order, as printed ("563 (11, 1)" holds 563, 11 and 1; "13,631" is one).
inline std::vector<std::string> printed_numbers(const std::string& text) {
  static const std::regex number(R"([-+]?\d{1,3}(?:,\d{3})+(?:\.\d+)?|[-+]?\d+(?:\.\d+)?)");
  std::vector<std::string> printed;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), number); it != std::sregex_iterator(); ++it) {
    printed.push_back(it->str());
  }
  return printed;
}

/// The value of a number as a page prints it ("13,631" is 13631).
inline double printed_value(std::string printed) {
  printed.erase(std::remove(printed.begin(), printed.end(), ','), printed.end());
  return std::strtod(printed.c_str(), nullptr);
}

/// Expects a number as a page prints it to be `value`: a decimal within one unit of its last digit (0.031 takes
/// 0.030 to 0.032), as the doc runner compares a console block's numbers; a whole number rounded (118 takes 117.99;
/// a count of 563 only 563). A failure names `where` and asks for the figure to be regenerated; `source` is what
/// gives the value (the code, or the page a figure is quoted from).
inline void expect_printed(const std::string& where, const std::string& printed, double value,
                           const std::string& source = "the code") {
  std::string digits = printed;
  digits.erase(std::remove(digits.begin(), digits.end(), ','), digits.end());
  const size_t point = digits.find('.');
  const double unit =
      point == std::string::npos ? 0.5 : std::pow(10.0, -static_cast<double>(digits.size() - point - 1));
  EXPECT_LE(std::abs(printed_value(digits) - value), unit * (1 + 1e-9))
      << where << " says " << printed << "; " << source << " gives " << value
      << " now: run the commands that measure it again and put their figures in";
}

/// Expects the numbers in one cell of such a row (in their order) to be `values` as printed (expect_printed).
inline void expect_doc_figures(const std::string& page, const std::string& after, const std::string& label,
                               size_t column, const std::vector<double>& values,
                               const std::string& source = "the code") {
  const std::string where = page + ", the table after \"" + after + "\", row \"" + label + "\"";
  const auto row = doc_table_row(page, after, label);
  ASSERT_GT(row.size(), column) << where << ": no such row or column " << column;
  const std::string& cell = row[column];
  const auto printed = printed_numbers(cell);
  ASSERT_EQ(printed.size(), values.size()) << where << ", column " << column << ": \"" << cell << "\"";
  for (size_t i = 0; i < values.size(); ++i) {
    expect_printed(where + ", column " + std::to_string(column) + " (\"" + cell + "\")", printed[i], values[i], source);
  }
}

/// The prose of `page` from the end of the first `from` to the next `to` after it, its lines joined by spaces:
/// where a sentence quotes figures a test measures. Empty when either is not there.
inline std::string doc_text_between(const std::string& page, const std::string& from, const std::string& to) {
  std::ifstream in(page.rfind('/', 0) == 0 ? page : std::string(DRIFTLAB_SOURCE_DIR) + "/" + page);
  std::string text, line;
  while (std::getline(in, line)) text += line + " ";
  const size_t begin = text.find(from);
  if (begin == std::string::npos) return "";
  const size_t end = text.find(to, begin + from.size());
  return end == std::string::npos ? "" : text.substr(begin + from.size(), end - begin - from.size());
}

/// Expects the figures of such a stretch of prose to be `values` as printed (expect_printed), NaN for a figure
/// another test checks (the README's sentence on Intel and ACES, each log's test checking its own).
inline void expect_doc_text_figures(const std::string& page, const std::string& from, const std::string& to,
                                    const std::vector<double>& values, const std::string& source = "the code") {
  const std::string where = page + ", the text after \"" + from + "\"";
  const std::string text = doc_text_between(page, from, to);
  ASSERT_FALSE(text.empty()) << where << ": no such text up to \"" << to << "\"";
  const auto printed = printed_numbers(text);
  ASSERT_EQ(printed.size(), values.size()) << where << ": \"" << text << "\"";
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isnan(values[i])) {
      expect_printed(where + ", figure " + std::to_string(i + 1), printed[i], values[i], source);
    }
  }
}

}  // namespace driftlab::test
