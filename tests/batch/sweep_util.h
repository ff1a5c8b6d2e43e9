// What the sweep tests share: the tiny sweep they run and how they read its table.
#pragma once

#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/test_util.h"

namespace driftlab::test {

inline const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

inline CmdResult driftlab(const std::string& args) { return run_capture(kDriftlab + " " + args); }

/// 2 IMU clock offsets x 2 seeds of 5 s of the default scenario through the estimator (late measurements
/// dropped, as robot_localization does), diagnosis and eval: 4 points of about a second each.
inline std::string write_tiny_spec(const TempDir& dir, const std::string& extra = "") {
  const std::string path = dir.file("tiny.yaml");
  std::ofstream(path) << "name: tiny\n"
                         "duration: 5\n"
                         "modules: estimator\n"
                         "settings:\n  estimator: {window_s: 0}\n"
                         "pipeline: [sim, replay, diagnose, eval]\n"
                         "vary:\n"
                         "  faults.IMU.clock_offset_s: [0, 0.05]\n"
                         "  seed: [1, 2]\n"
                      << extra;
  return path;
}

/// The rows of DIR/results.json.
inline nlohmann::json result_rows(const std::string& dir) {
  std::ifstream f(dir + "/results.json");
  return nlohmann::json::parse(f)["rows"];
}

/// id -> what a point computed (its row without times, attempts and hosts), to compare two runs of a sweep.
inline std::map<std::string, std::string> metrics_by_id(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (auto row : result_rows(dir)) {
    for (auto it = row.begin(); it != row.end();) {
      const std::string k = it.key();
      it = (k.rfind("seconds.", 0) == 0 || k == "attempts") ? row.erase(it) : std::next(it);
    }
    out[row["id"]] = row.dump();
  }
  return out;
}

}  // namespace driftlab::test
