// Small helpers shared by the subcommands: errors, number formatting, progress on a TTY.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/number_text.h"
#include "core/result.h"

namespace driftlab::apps {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;

/// The help of a command's log argument.
inline constexpr char kLogInputHelp[] =
    "LCM log, or another tool's recording (a ROS 1 or ROS 2 bag, a bag folder, an MCAP file, a CARMEN log; the files "
    "of "
    "a split recording; a PX4 flight log beside a bag of the same flight, put on its clock): converted once, kept "
    "beside it";

/// Prints "driftlab: message" as one line on stderr and returns code.
int fail(std::string_view message, int code = kExitBadInput);

/// From now on Ctrl-C and SIGTERM set the returned flag, which the long commands watch to stop cleanly (what is
/// finished is kept, a log is closed whole).
const std::atomic<bool>* stop_on_signals();

/// This program's path, to run its own subcommands ("driftlab" when it cannot be found).
std::string self_path();

/// The exit code for an error, by its code: kExitFailure (1) when an output could not be written (the
/// environment), kExitBadInput (2) otherwise (the input).
int exit_code_for(const Error& error);

/// A command run in-process (the Python module, python/): while one lives on a thread, fail() on that thread keeps
/// the first message in `error` instead of printing it, and write_output("-") appends to `text` instead of writing
/// to standard output. Not nested.
struct OutputCapture {
  std::string error;  ///< the first message given to fail(), without "driftlab: "
  std::string text;   ///< what write_output("-") was given
  OutputCapture();
  ~OutputCapture();
  OutputCapture(const OutputCapture&) = delete;
  OutputCapture& operator=(const OutputCapture&) = delete;
};

/// Writes text to path, or to standard output when path is "-". On failure prints one line naming the file and
/// returns false.
bool write_output(const std::string& path, const std::string& text);

}  // namespace driftlab::apps
