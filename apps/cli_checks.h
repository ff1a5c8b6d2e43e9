// Number checks for command-line options, with the ranges of the declarative config layer (core/config.h): one
// Range type, one violation text ("must be > 0", "is outside 0..60 s") for YAML values and options alike. An option
// is refused in one line, "--rate: must be > 0, got -1" (CLI11's own checks print the largest double in full).
// parse_and_run (apps/tools.cc) refuses NaN, infinities and integers beyond their type for every option, and
// aborts at start-up on a number option without a range, so none can be added without one.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "core/config.h"
#include "core/result.h"

namespace driftlab::apps {

/// The name of every validator made by in_range, by which parse_and_run tells that a number option has its range.
inline constexpr const char* kRangeCheck = "range";

/// A check that the option's value (each value, for a list) is a finite number within r, else "must be a finite
/// number, got V" or r's violation (naming unit, when given) and ", got V". --help shows the range as an interval
/// after the type ("FLOAT:(0, 1e+06]").
CLI::Validator in_range(config::Range r, const std::string& unit = "");

/// Ranges shared by several commands.
/// Simulated time [s]: as the scenario's `duration` (sim/scenario.cc).
inline constexpr config::Range kSimDuration = config::above(0, 1e7);
/// Random seeds: every whole number a double holds exactly (2^53 - 1), so the check itself is exact.
inline constexpr config::Range kSeed = config::between(0, 9007199254740991.0);
/// Pacing against the wall clock, as a multiple of real time.
inline constexpr config::Range kPaceRate = config::above(0, 1e6);

/// An option whose words name an enum's values, each value's word being its to_string ("--align posyaw" sets
/// *target to AlignmentType::kPosYaw): the library's option declared once, its words and default shown by --help as
/// a CLI::IsMember option shows them ("TEXT:{none,se3,...} [none]").
template <class E>
CLI::Option* add_choice(CLI::App* cmd, const std::string& name, E* target, std::initializer_list<E> values,
                        const std::string& help) {
  std::vector<std::string> words;
  for (E v : values) words.emplace_back(to_string(v));
  auto set = [target, all = std::vector<E>(values)](const std::string& word) {
    for (E v : all) {
      if (word == to_string(v)) *target = v;
    }
  };
  return cmd->add_option_function<std::string>(name, set, help)
      ->default_str(to_string(*target))
      ->check(CLI::IsMember(words));
}

/// `--json` and `--json-out FILE`, meaning the same in every command: --json prints one JSON object on standard
/// output instead of the text; --json-out writes it to FILE as well (the text still printed, unless --json).
struct JsonOutput {
  bool print = false;
  std::string file;
  bool wanted() const { return print || !file.empty(); }
  /// Writes text (one JSON object) where asked; false, with one line naming the file, when FILE could not be
  /// written.
  bool emit(const std::string& text) const;
  /// Refuses FILE, before anything is written, when it is one of `inputs` (or inside an input folder), not a
  /// plain file (a FIFO, a device), or the same path as one of the command's own `outputs`.
  Status check(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs = {}) const;
};
/// Adds --json and --json-out to cmd; `what` names the object ("the diagnosis", "a summary").
void add_json_options(CLI::App* cmd, JsonOutput* out, const std::string& what);

/// The range as --help shows it: "[0, 60]", "(0, 1e+06]", "[1, 4096]".
std::string interval(const config::Range& r);

}  // namespace driftlab::apps
