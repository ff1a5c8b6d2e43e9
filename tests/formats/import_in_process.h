// A recording imported in the test's own process (formats::import_log), for the tests of what the import makes of
// a file: the problems it reports, the summary `driftlab import` prints, the log it writes. The command's own
// contract (its exit codes, its "driftlab: " lines) is tested on the program, in tests/apps/.
#pragma once

#include <string>
#include <vector>

#include "formats/import.h"

namespace driftlab::test {

struct Imported {
  std::string error;                  ///< why nothing was converted (the Error's message), or empty
  std::vector<std::string> problems;  ///< each part left out, one line naming the file and the place
  std::string text;                   ///< what `driftlab import` prints of it (formats::import_text)
  formats::ImportSummary summary;
  /// What it said: the error, or the problems, one line each.
  std::string said() const {
    std::string all = error.empty() ? "" : error + "\n";
    for (const auto& p : problems) all += p + "\n";
    return all;
  }
};

/// Imports inputs (one recording) into out.
inline Imported import_in_process(const std::vector<std::string>& inputs, const std::string& out) {
  Imported r;
  auto s = formats::import_log(inputs, out, [&r](const std::string& p) { r.problems.push_back(p); });
  if (!s) {
    r.error = s.error().message;
    return r;
  }
  r.summary = *s;
  r.text = formats::import_text(*s, inputs.at(0), out);
  return r;
}

}  // namespace driftlab::test
