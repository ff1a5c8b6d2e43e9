// Running the 2D SLAM module on the real CARMEN logs (../shared/data/carmen: Intel Research Lab, ACES building)
// the way a user does: `driftlab import` of the ROS bag, `driftlab replay --modules slam`, `driftlab eval`.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <string>

#include "tests/test_util.h"

namespace driftlab::test {

inline const std::string kDriftlabProgram = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

/// The bag's topics for the slam module (docs/tutorial-public-dataset.md uses the same file).
inline std::string carmen_slam_config(const TempDir& dir) {
  std::string path = dir.file("slam.yaml");
  std::ofstream(path)
      << "slam:\n  2d:\n    scan_channel: /scan\n    odom_channel: /odom\n    tf_static_channel: /tf_static\n";
  return path;
}

/// `driftlab ARGS` with its output parsed as JSON (ARGS end in `--json`); a failed run fails the test.
inline nlohmann::json driftlab_json(const std::string& args) {
  const auto r = run_capture(kDriftlabProgram + " " + args);
  EXPECT_EQ(r.code, 0) << args << "\n" << r.err;
  if (r.code != 0) return {};
  return nlohmann::json::parse(r.out, nullptr, false);
}

/// The relation error (Kuemmerle et al.) of a pose source against a relations file: `driftlab eval --relations`.
inline nlohmann::json relation_error(const std::string& est, const std::string& relations) {
  return driftlab_json("eval --est " + est + " --relations " + relations + " --json")["relations"];
}

}  // namespace driftlab::test
