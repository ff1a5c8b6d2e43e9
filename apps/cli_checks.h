// Number checks for command-line options, with readable messages ("must be > 0, got -1"): CLI11's own print the
// largest double in full. NaN, infinities and integers beyond their type are refused for every option by
// parse_and_run (apps/tools.cc).
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdlib>
#include <string>

namespace driftlab::apps {

/// A check that the option's value v satisfies ok(v), else "must be WHAT, got V".
template <typename F>
CLI::Validator number_check(const char* what, F ok, const char* help_tag = "") {
  return CLI::Validator(
      [what, ok](std::string& v) -> std::string {
        char* end = nullptr;
        const double d = std::strtod(v.c_str(), &end);
        if (end == v.c_str() || *end != '\0') return "";  // not a number: the conversion says so
        if (!std::isfinite(d)) return "must be a finite number, got " + v;
        return ok(d) ? "" : std::string("must be ") + what + ", got " + v;
      },
      help_tag);
}

inline CLI::Validator positive() {
  return number_check("> 0", [](double d) { return d > 0; }, "POSITIVE");
}
inline CLI::Validator non_negative() {
  return number_check(">= 0", [](double d) { return d >= 0; }, "NONNEGATIVE");
}

}  // namespace driftlab::apps
