// Running the 2D SLAM module on the real CARMEN logs (../shared/data/carmen: Intel Research Lab, ACES building)
// the way a user does: `driftlab import` of the ROS bag, `driftlab replay --modules slam`, `driftlab eval`.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "driftlab/loop_closure_t.hpp"
#include "driftlab/pose_t.hpp"
#include "tests/doc_figures.h"
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

/// A run's figures in a table of docs/slam.md (the one after the line holding `table`): from `column` on, the row
/// `label` holds the relation error's mean and maximum and the loop closures with those refused by chi2 and those
/// undone; `metrics` are the replay's, `error` relation_error's.
inline void expect_run_row(const std::string& table, const std::string& label, size_t column,
                           const nlohmann::json& metrics, const nlohmann::json& error) {
  const auto metric = [&](const char* name) { return metrics[name].get<double>(); };
  expect_doc_figures("docs/slam.md", table, label, column, {error["trans_m"]["mean"].get<double>()});
  expect_doc_figures("docs/slam.md", table, label, column + 1, {error["trans_m"]["max"].get<double>()});
  expect_doc_figures("docs/slam.md", table, label, column + 2,
                     {metric("loop_closures"), metric("loop_rejected_chi2"), metric("loop_undone")});
}

/// docs/slam.md's table of every benchmark log: the row `label` holds a run's scans, then its figures as above; a
/// bag's run (`label` ending in "(bag)") also has a row in the table against published figures, with the relation
/// error's mean and standard deviation in translation and in rotation.
inline void expect_benchmark_row(const std::string& label, const nlohmann::json& metrics, const nlohmann::json& error) {
  const std::string table = "### Every benchmark log we could obtain";
  expect_doc_figures("docs/slam.md", table, label, 1, {metrics["scans"].get<double>()});
  expect_run_row(table, label, 2, metrics, error);
  if (!label.ends_with("(bag)")) return;
  const std::string published = "**Against what others publish on the same relations.**";
  expect_doc_figures("docs/slam.md", published, label, 1,
                     {error["trans_m"]["mean"].get<double>(), error["trans_m"]["std"].get<double>()});
  expect_doc_figures("docs/slam.md", published, label, 2,
                     {error["rot_deg"]["mean"].get<double>(), error["rot_deg"]["std"].get<double>()});
}

/// docs/slam.md's two tables of what the odometry's heading says of a log ("Odometry in the match"): their rows
/// `label` hold the defaults' run's `odometry_heading_q90` (then `also`, where the row has more) and
/// `match_odometry_auto_q90`.
inline void expect_heading_rows(const std::string& label, const nlohmann::json& metrics,
                                const std::vector<double>& also = {}) {
  std::vector<double> heading = {metrics["odometry_heading_q90"].get<double>()};
  heading.insert(heading.end(), also.begin(), also.end());
  expect_doc_figures("docs/slam.md", "**Which logs it suits: the odometry's heading against the matches.**", label, 1,
                     heading);
  expect_doc_figures("docs/slam.md", "**`auto`, the default: the log decides.**", label, 1,
                     {metrics["match_odometry_auto_q90"].get<double>()});
}

/// SLAM_LOOPS says what became of every loop test: one final record per test, in the counts the metrics give, and
/// each closure kept sits where the final graph puts its two keyframes.
inline void check_loop_records(const std::string& out, const nlohmann::json& metrics) {
  std::map<int64_t, std::array<double, 3>> trajectory;  // by scan stamp
  std::vector<driftlab::loop_closure_t> records;
  for (const auto& e : test::read_all(out)) {
    if (e.channel == "SLAM_TRAJECTORY") {
      const auto p = test::decode<driftlab::pose_t>(e);
      trajectory[p.header.utime] = {p.position.x, p.position.y, 2 * std::atan2(p.orientation.z, p.orientation.w)};
    } else if (e.channel == "SLAM_LOOPS") {
      records.push_back(test::decode<driftlab::loop_closure_t>(e));
    }
  }
  std::map<std::string, double> count;
  std::set<std::pair<int32_t, int32_t>> undone;
  for (const auto& r : records) {
    ++count[r.outcome];
    if (r.outcome == "undone") undone.insert({r.keyframe, r.old_keyframe});
    EXPECT_FALSE(r.reason.empty()) << r.outcome;
    EXPECT_EQ(r.reason.find(','), std::string::npos) << r.reason;  // one CSV field, unquoted
    EXPECT_LT(r.old_utime, r.header.utime);
    EXPECT_TRUE(trajectory.count(r.header.utime) && trajectory.count(r.old_utime)) << "keyframes are scans";
  }
  const auto metric = [&](const char* name) { return metrics[name].get<double>(); };
  EXPECT_EQ(count["accepted"] + count["low_overlap"] + count["ambiguous"] + count["not_unique"] +
                count["refused_chi2"] + count["unconfirmed"],
            metric("loop_tests"));
  EXPECT_EQ(count["accepted"] - count["undone"], metric("loop_closures"));
  EXPECT_EQ(count["undone"], metric("loop_undone"));
  EXPECT_EQ(count["low_overlap"], metric("loop_rejected_goodness"));
  EXPECT_EQ(count["ambiguous"] + count["not_unique"], metric("loop_rejected_unique"));
  EXPECT_EQ(count["refused_chi2"], metric("loop_rejected_chi2"));
  EXPECT_EQ(count["unconfirmed"], metric("loop_unconfirmed"));
  EXPECT_GE(count["waiting"], count["unconfirmed"]);  // each unconfirmed match waited first
  // A kept closure is an edge of 2 cm standard deviation (along what the match pins down) in the optimised graph:
  // most sit within it (Intel: median 6 mm, 90% within 2.4 cm; along a corridor one may be off by more). A
  // record naming the wrong keyframes, or the edge in the wrong frame, is off by metres.
  std::vector<double> off;
  for (const auto& r : records) {
    if (r.outcome != "accepted" || undone.count({r.keyframe, r.old_keyframe})) continue;
    const auto& a = trajectory[r.old_utime];
    const auto& b = trajectory[r.header.utime];
    const double c = std::cos(a[2]), s = std::sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
    off.push_back(std::hypot(c * dx + s * dy - r.measured[0], -s * dx + c * dy - r.measured[1]));
  }
  ASSERT_FALSE(off.empty());
  std::nth_element(off.begin(), off.begin() + static_cast<std::ptrdiff_t>(off.size() / 2), off.end());
  EXPECT_LT(off[off.size() / 2], 0.02);
}

}  // namespace driftlab::test
