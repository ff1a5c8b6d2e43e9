// A damaged log made clean: every intact event written, in file order with its log time, into a log any LCM tool
// reads to the end, and a record of what was left out (`driftlab recover`, as `mcap recover` does for MCAP files).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/log_index.h"
#include "core/result.h"

namespace driftlab::recorder {

struct RecoverOptions {
  /// Keep intact events whose message, of a driftlab type, does not hold its type's layout (other tools'
  /// decoders would throw on them).
  bool keep_malformed = false;
  std::function<void(uint64_t done, uint64_t total)> progress;  ///< bytes read of the log's size
};

struct Recovery {
  std::string log, out;
  int64_t events = 0;  ///< written
  uint64_t bytes_in = 0, bytes_out = 0, bytes_damaged = 0;
  uint64_t problems_total = 0;    ///< damaged spots met
  std::vector<Problem> problems;  ///< the first LogIndex::kMaxStoredProblems of them
  /// Intact events left out because their channel's name is longer than LCM's tools take (255 bytes).
  int64_t long_channels = 0;
  struct Malformed {
    int64_t count = 0;
    std::string first;  ///< why the first one was left out
  };
  std::map<std::string, Malformed, std::less<>> malformed;  ///< by channel
};

/// Writes `out` (atomically: it appears whole or not at all). Errors: the log is not an LCM event log or cannot be
/// read (bad input), or `out` cannot be written (named).
Result<Recovery> recover_log(const std::string& log, const std::string& out, const RecoverOptions& options);

/// `recover --json`.
nlohmann::json to_json(const Recovery& r);
/// The lines of `driftlab recover`: what was written, then what was left out and why, with up to `max_problems`
/// damaged spots listed.
std::string recovery_text(const Recovery& r, int max_problems);

}  // namespace driftlab::recorder
