// The 2D SLAM module on the whole of two public real logs, the SLAM benchmark's Intel Research Lab and ACES
// building (../shared/data/carmen), end to end as a user runs it: the ROS bag imported, replayed through the slam
// module with its defaults, scored by `driftlab eval` against the benchmark's relations (Kuemmerle et al. 2009)
// and against GMapping's corrected trajectory, and against MRPT's icp-slam on the same data in the same run.
// About 30 s in the normal build; too slow under the sanitizers, so its own binary whose label scripts/test leaves
// out there (slam_tests runs the first 500 s of Intel, sanitizers included).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "analyzers/relations.h"
#include "analyzers/trajectory_io.h"
#include "core/log_reader.h"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/validate.h"
#include "tests/carmen_reference.h"
#include "tests/slam/carmen_slam.h"
#include "tests/slam/icp_slam.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

/// icp-slam's path on a rawlog `driftlab export rawlog` made from `log` (one step per scan or odometry message,
/// in the log's order), at the scans' stamps, as a TUM file.
void icp_slam_tum(const std::string& log, const std::string& path_txt, const std::string& tum) {
  std::vector<int64_t> scan_stamp;  // per step: the scan's stamp, or -1 for an odometry step
  auto reader = LogReader::open(log);
  ASSERT_TRUE(reader);
  Event e;
  while (reader->next(e)) {
    laser_scan_t scan;
    odometry_t odometry;
    if (lcmtypes::decode(e.data, scan) && scan.nranges >= 2) {
      scan_stamp.push_back(scan.header.utime);
    } else if (lcmtypes::decode(e.data, odometry)) {
      scan_stamp.push_back(-1);
    }
  }
  std::ifstream in(path_txt);
  std::ofstream out(tum);
  size_t step;
  double x, y, yaw;
  int scans = 0;
  while (in >> step >> x >> y >> yaw) {
    ASSERT_LT(step, scan_stamp.size());
    if (scan_stamp[step] < 0) continue;
    char line[200];
    std::snprintf(line, sizeof(line), "%.6f %.6f %.6f 0 0 0 %.9f %.9f\n", static_cast<double>(scan_stamp[step]) * 1e-6,
                  x, y, std::sin(yaw / 2), std::cos(yaw / 2));
    out << line;
    ++scans;
  }
  EXPECT_GT(scans, 1000);
}

/// A CARMEN log of a bag's scans as the benchmark's raw .clf files have them: one FLASER line per scan, in the
/// bag's order, with the odometry at its stamp (interpolated between the odometry messages around it) as both the
/// laser's and the odometry's pose, and no ODOM lines. Both of a line's times are the scan's stamp.
void write_clf(const std::string& log, const std::string& clf) {
  std::vector<laser_scan_t> scans;
  std::vector<std::pair<int64_t, std::array<double, 3>>> odometry;
  auto reader = LogReader::open(log);
  ASSERT_TRUE(reader);
  Event e;
  while (reader->next(e)) {
    laser_scan_t scan;
    odometry_t o;
    if (lcmtypes::decode(e.data, scan)) {
      scans.push_back(std::move(scan));
    } else if (lcmtypes::decode(e.data, o)) {
      const auto& q = o.orientation;
      odometry.push_back(
          {o.header.utime,
           {o.position.x, o.position.y, std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))}});
    }
  }
  std::sort(odometry.begin(), odometry.end());
  ASSERT_GT(odometry.size(), 100u);
  std::ofstream out(clf);
  out << "# CARMEN Logfile written by a driftlab test\n";
  char num[64];
  for (const auto& scan : scans) {
    const int64_t t = scan.header.utime;
    auto hi =
        std::lower_bound(odometry.begin(), odometry.end(), t, [](const auto& a, int64_t v) { return a.first < v; });
    std::array<double, 3> pose;
    if (hi == odometry.begin()) {
      pose = hi->second;
    } else if (hi == odometry.end()) {
      pose = odometry.back().second;
    } else {
      const auto& lo = *std::prev(hi);
      const double f = static_cast<double>(t - lo.first) / static_cast<double>(hi->first - lo.first);
      const double dyaw = std::remainder(hi->second[2] - lo.second[2], 2 * M_PI);
      pose = {lo.second[0] + f * (hi->second[0] - lo.second[0]), lo.second[1] + f * (hi->second[1] - lo.second[1]),
              lo.second[2] + f * dyaw};
    }
    out << "FLASER " << scan.nranges;
    for (float r : scan.ranges) {
      std::snprintf(num, sizeof(num), " %.3f", r);
      out << num;
    }
    std::snprintf(num, sizeof(num), " %.6f %.6f %.6f", pose[0], pose[1], std::remainder(pose[2], 2 * M_PI));
    out << num << num;
    std::snprintf(num, sizeof(num), " %.6f nohost %.6f\n", static_cast<double>(t) * 1e-6,
                  static_cast<double>(t) * 1e-6);
    out << num;
  }
}

struct Dataset {
  const char* name;
  size_t relations;
  const char* label;     ///< its rows in docs/slam.md's tables ...
  const char* accuracy;  ///< ... but the one of "Accuracy on real data"
};

/// docs/slam.md's table of the logs with `match_odometry: true` ("Odometry in the match"): the row `label` holds
/// what the log `raw` (imported) gives with it, scored against `relations` (test::expect_run_row). Returns the mean.
double expect_match_odometry_row(const std::string& label, const test::TempDir& dir, const std::string& raw,
                                 const std::string& relations) {
  std::ofstream(dir.file("match-odometry.yaml")) << "slam:\n  2d: {match_odometry: true}\n";
  const std::string out = dir.file("match-odometry.lcm");
  const auto replay = test::driftlab_json("replay " + raw + " --modules slam --config " +
                                          dir.file("match-odometry.yaml") + " --json -o " + out);
  const auto error = test::relation_error(out + ":SLAM_TRAJECTORY", relations);
  test::expect_run_row("### Odometry in the match", label, 1, replay["modules"][0]["metrics"], error);
  return error["trans_m"]["mean"].get<double>();
}

class SlamOnTheBenchmark : public ::testing::TestWithParam<Dataset> {};

TEST_P(SlamOnTheBenchmark, ClosesLoopsToCentimetresAndBeatsIcpSlam) {
  const Dataset& run = GetParam();
  const auto files = test::carmen_run(run.name);
  if (files.empty()) return;
  const std::string& relations = files.relations;
  test::TempDir dir;
  const std::string raw = dir.file("raw.lcm"), out = dir.file("slam.lcm");
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + raw + " >/dev/null"), 0);
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.corrected + " -o " + dir.file("corrected.lcm") +
                      " >/dev/null"),
            0);
  const std::string config = test::carmen_slam_config(dir);

  // No config: the module finds the bag's /scan, /odom and /tf_static by type and says so.
  const auto replay = test::driftlab_json("replay " + raw + " --modules slam --json -o " + out);
  const std::string notes = replay["notes"].dump();
  for (const char* found : {"scans from /scan", "odometry from /odom", "mounting from /tf_static"}) {
    EXPECT_NE(notes.find(found), std::string::npos) << notes;
  }
  const auto& metrics = replay["modules"][0]["metrics"];
  std::printf("%s: %s\n", run.name, metrics.dump().c_str());
  EXPECT_GT(metrics["loop_closures"].get<double>(), 20);
  EXPECT_TRUE(replay["modules"][0]["warnings"].empty()) << replay["modules"][0]["warnings"];
  test::check_loop_records(out, metrics);
  // Every matched scan but the first (no prediction yet) checks the odometry's heading against its noise model.
  // On both logs it turns further from the matches than the model says: 90% within 2.0 of its standard deviations
  // would be what a true model gives (1.645) and some slack; ours 3.88 on Intel, 2.88 on ACES. So the defaults
  // leave slam.2d.match_odometry off here, rightly: it folds Intel (SlamMatchOdometry).
  EXPECT_EQ(
      metrics["odometry_heading_checks"].get<double>(),
      metrics["scans"].get<double>() - metrics["scans_still"].get<double>() - metrics["unmatched"].get<double>() - 1);
  EXPECT_GT(metrics["odometry_heading_q90"].get<double>(), 2.0);
  // match_odometry auto (the default) decides by the same figure over the first 600 checks, taken with the odometry
  // out of the match: on at 2.2 or less (docs/slam.md, "auto"). Off on both (ours 3.24 on Intel, 2.91 on ACES),
  // and then the run is the one match_odometry false gives, to the last digit: the same messages out (poses as
  // published and as last optimised, loop records, map).
  EXPECT_EQ(metrics["match_odometry_auto"].get<double>(), 0);
  EXPECT_GT(metrics["match_odometry_auto_q90"].get<double>(), 2.2);
  EXPECT_EQ(metrics.count("scans_weighed"), 0u);
  std::ofstream(dir.file("off.yaml")) << "slam:\n  2d: {match_odometry: false}\n";
  ASSERT_EQ(test::run(test::kDriftlabProgram + " replay " + raw + " --modules slam --config " + dir.file("off.yaml") +
                      " -o " + dir.file("off.lcm") + " >/dev/null 2>&1"),
            0);
  const auto ours_out = test::messages_on(out, "SLAM_");
  EXPECT_GT(ours_out.size(), static_cast<size_t>(2 * metrics["scans"].get<double>()));
  EXPECT_TRUE(ours_out == test::messages_on(dir.file("off.lcm"), "SLAM_"));
  // The bag in the order CARMEN's logger wrote it, and the same replayed in stamp order: Intel's scans and odometry
  // step back up to 0.9 s (602 and 631 times), and the module waits for each stream by how late it has shown its
  // messages to come, so the same messages out. Matched as they arrived, it gave 0.0309 m against 0.0320 m in
  // stamp order (563 and 558 closures), and published 339 poses out of stamp order.
  ASSERT_EQ(
      test::run(test::kDriftlabProgram + " replay " + raw + " --modules slam --order stamp --reorder-window 2 -o " +
                dir.file("stamp-order.lcm") + " >/dev/null 2>&1"),
      0);
  EXPECT_TRUE(ours_out == test::messages_on(dir.file("stamp-order.lcm"), "SLAM_"));

  // The trajectory as last optimised, against the benchmark's relations: loop-closing SLAM reaches 0.02-0.07 m
  // on these logs in the literature, scan matching alone about 0.2 m; 0.10 m is the bar (ours: 0.032 m
  // on Intel, 0.048 m on ACES).
  const auto ours = test::relation_error(out + ":SLAM_TRAJECTORY", relations);
  EXPECT_EQ(ours["used"].get<size_t>(), run.relations);
  const double mean = ours["trans_m"]["mean"].get<double>();
  EXPECT_LT(mean, 0.10);
  // No relation 1.5 m off or more: a map folded by a wrong or missed closure is metres off (the bar; ours
  // 0.74 m on Intel, 0.78 m on ACES).
  EXPECT_LT(ours["trans_m"]["max"].get<double>(), 1.5);
  // docs/slam.md shows these figures: its table of every benchmark log and its tables of the odometry's heading.
  test::expect_benchmark_row(std::string(run.label) + " (bag)", metrics, ours);
  test::expect_heading_rows(run.label, metrics);

  // The figure belongs to the kind of recording, not to this file: the same log started 3 s and 10 s later is
  // another recording of the building (other keyframes, other loops), and must meet the same bar. Ours: Intel
  // 0.030 m (max 0.87 m) and 0.029 m (0.56 m), ACES 0.045 m (0.48 m) and 0.045 m (0.71 m);
  // docs/tutorial-public-dataset.md shows Intel's.
  for (const char* start : {"3", "10"}) {
    const std::string later = dir.file(std::string("from-") + start + ".lcm");
    ASSERT_EQ(test::run(test::kDriftlabProgram + " replay " + raw + " --modules slam --start " + start + " -o " +
                        later + " >/dev/null 2>&1"),
              0);
    const auto error = test::relation_error(later + ":SLAM_TRAJECTORY", relations);
    const double later_mean = error["trans_m"]["mean"].get<double>(), later_max = error["trans_m"]["max"].get<double>();
    std::printf("%s from %s s: relation error %.4f m, max %.3f m over %zu relations\n", run.name, start, later_mean,
                later_max, error["used"].get<size_t>());
    EXPECT_GT(error["used"].get<size_t>(), run.relations * 9 / 10) << start;  // only those of the first seconds go
    EXPECT_LT(later_mean, 0.10) << start;
    EXPECT_LT(later_max, 1.5) << start;
  }

  // Against GMapping's corrected trajectory (its scans matched to ours by their readings), aligned in the plane:
  // below 0.3 m (ours: 0.14 m on Intel, 0.16 m on ACES; plain scan matching is off by metres after a loop).
  auto gmapping = test::corrected_at_raw_stamps(raw, dir.file("corrected.lcm"));
  ASSERT_TRUE(gmapping) << gmapping.error().message;
  ASSERT_TRUE(analyzers::write_tum(dir.file("corrected.tum"), *gmapping).ok());
  const auto ate = test::driftlab_json("eval --gt " + dir.file("corrected.tum") + " --est " + out +
                                       ":SLAM_TRAJECTORY --align posyaw --max-dt 0.0001 --json")["ate"];
  EXPECT_LT(ate["rmse"].get<double>(), 0.3);
  // The poses as published scan by scan carry the drift since the last loop closure, and move with a closure by
  // as much as it corrects, no more: before the loop closures, a stale index in the map sent them 7-40 m back to
  // the start. The largest correction on these logs: Intel's far return at 2,493 s, 3.4 m and 13 degrees, where
  // the published poses are 3.1 m from GMapping's at most; 5 m is above that and below the stale index's 7 m
  // (ours: 0.53 m RMS on Intel, max 3.06 m; 0.39 m and 0.84 m on ACES).
  const auto online = test::driftlab_json("eval --gt " + dir.file("corrected.tum") + " --est " + out +
                                          ":SLAM_POSE --align posyaw --max-dt 0.0001 --json")["ate"];
  EXPECT_LT(online["rmse"].get<double>(), 1.0);
  EXPECT_LT(online["max"].get<double>(), 5.0);

  // --restamp auto applies only corrections the diagnosis is sure of: on these logs it leaves SLAM within 2%.
  const auto restamped = test::driftlab_json("replay " + raw + " --modules slam --config " + config +
                                             " --restamp auto --json -o " + dir.file("restamped.lcm"));
  ASSERT_FALSE(restamped.is_null());
  const double restamped_mean =
      test::relation_error(dir.file("restamped.lcm") + ":SLAM_TRAJECTORY", relations)["trans_m"]["mean"].get<double>();
  EXPECT_NEAR(restamped_mean, mean, 0.02 * mean);

  // MRPT's icp-slam, its demo configuration, on the same scans and odometry (`driftlab export rawlog`).
  ASSERT_EQ(
      test::run(test::kDriftlabProgram + " export rawlog " + raw + " -o " + dir.file("raw.rawlog") + " >/dev/null"), 0);
  ASSERT_EQ(test::run_icp_slam(dir, dir.file("raw.rawlog")), 0);
  ASSERT_NO_FATAL_FAILURE(icp_slam_tum(raw, dir.file("icp/log_estimated_path.txt"), dir.file("icp.tum")));
  const double peer = test::relation_error(dir.file("icp.tum"), relations)["trans_m"]["mean"].get<double>();
  std::printf("%s: relation error %.4f m (icp-slam %.4f m), ATE %.4f m, as published %.4f m\n", run.name, mean, peer,
              ate["rmse"].get<double>(), online["rmse"].get<double>());
  EXPECT_LT(mean, peer);
  // docs/slam.md, "Accuracy on real data", shows these.
  const std::string page = "docs/slam.md", table = "### Accuracy on real data";
  test::expect_doc_figures(page, table, run.accuracy, 1, {mean, ours["rot_deg"]["mean"].get<double>()});
  test::expect_doc_figures(page, table, run.accuracy, 2, {ate["rmse"].get<double>()});
  test::expect_doc_figures(page, table, run.accuracy, 3, {online["rmse"].get<double>()});
  test::expect_doc_figures(page, table, run.accuracy, 4, {peer});
  test::expect_doc_figures(page, table, run.accuracy, 5, {metrics["loop_closures"].get<double>()});
  // The README's sentence on the 2D SLAM quotes both logs' relation errors, ours in cm, icp-slam's as it reads best
  // (Intel's in m), and docs/slam.md's opening both in m, between the literature's 0.02-0.07 m; each log's test
  // checks its own.
  const bool intel = std::string(run.name) == "intel";
  test::expect_doc_text_figures(
      "README.md", "a sparse Levenberg-Marquardt):", "; MRPT's ICP map",
      intel ? std::vector<double>{100 * mean, NAN, peer, NAN} : std::vector<double>{NAN, 100 * mean, NAN, 100 * peer});
  test::expect_doc_text_figures(page, "its relation error is", "for MRPT's `icp-slam` on the same data",
                                intel ? std::vector<double>{mean, NAN, NAN, NAN, peer, NAN}
                                      : std::vector<double>{NAN, mean, NAN, NAN, NAN, peer});

  // The same building as the CARMEN log the benchmark distributes: a .clf whose odometry rides on its FLASER
  // lines, with no ODOM lines. The module takes the scans' pose stream (FLASER_POSE) as its prior, and since that
  // cannot lag the scans, waits for late scans itself to match them in stamp order. Same scans, but the odometry
  // interpolated at the scans' stamps (as CARMEN's logger does) and the ranges in millimetres, so other keyframes
  // and other loops: within 1 cm of the bag's error, the spread of ACES's error over such changes (0.046-0.055 m
  // with the edges' deviations from 1.5 to 3 cm, or the odometry interpolated), and under the 0.10 m bar (Intel:
  // 0.028 m from the .clf, 0.032 m from the bag; ACES 0.047 and 0.048 m; before, with the odometry ignored, 1,761
  // of 1,983 scans of such a log went unmatched and the error was 0.52 m; with it but matched in arrival order,
  // 1.75 m). SlamOnMoreLogs runs a .clf of the benchmark's own against its bag.
  ASSERT_NO_FATAL_FAILURE(write_clf(raw, dir.file("flaser.clf")));
  const auto clf =
      test::driftlab_json("replay " + dir.file("flaser.clf") + " --modules slam --json -o " + dir.file("clf-slam.lcm"));
  EXPECT_NE(clf["notes"].dump().find("odometry from FLASER_POSE"), std::string::npos) << clf["notes"];
  EXPECT_TRUE(clf["modules"][0]["warnings"].empty()) << clf["modules"][0]["warnings"];
  const auto from_clf = test::relation_error(dir.file("clf-slam.lcm") + ":SLAM_TRAJECTORY", relations);
  EXPECT_EQ(from_clf["used"].get<size_t>(), run.relations);
  const double clf_mean = from_clf["trans_m"]["mean"].get<double>();
  std::printf("%s: relation error from the .clf %.4f m, from the bag %.4f m\n", run.name, clf_mean, mean);
  EXPECT_LT(clf_mean, mean + 0.01);
  EXPECT_LT(clf_mean, 0.10);
}

// Further logs of the SLAM benchmark, run when they are in ../shared/data/carmen or $DRIFTLAB_CARMEN_DATA (the
// closing note of issue 30 names them; until they are added this test is skipped, under CI too): Freiburg building 079
// (4,933 scans) and MIT CSAIL (1,988 scans) as INESC TEC's ricoslam converted them to ROS bags, and MIT CSAIL's own
// CARMEN .clf as the benchmark distributes it (odometry only on its FLASER lines). The bar is the issue's: mean
// relation error below 0.10 m and no relation off by 1.5 m or more (a map folded by a wrong or missed loop closure is
// metres off). Ours: 0.062 m (max 0.24 m) and 0.037 m (max 0.59 m), the same from the .clf. And MIT Killian's .clf
// (the benchmark's site has it; ricoslam's snapshot lists it without its content): a .clf written from ricoslam's
// bag with the relations' stamps (SlamOnKillian's renumbering) gives 0.055 m (max 0.88 m).
struct MoreLog {
  const char* name;
  const char* log;  ///< under ../shared/data/carmen
  const char* relations;
  const char* settings = "";  ///< slam.2d settings other than the defaults (YAML flow mapping), if any
  const char* warning = "";   ///< what the module's one warning says, if it has one
  const char* row = "";       ///< its row in docs/slam.md's table of every benchmark log, if it has one
  const char* label = "";     ///< its rows in docs/slam.md's tables of the odometry in the match, if it has them
  /// The same log as another converter stamped it, if the relations are on that one's stamps: they are put on this
  /// log's scans by their order (scan i of the one is scan i of the other).
  const char* stamps_of = "";
};

class SlamOnMoreLogs : public ::testing::TestWithParam<MoreLog> {};

/// A file of the benchmark in $DRIFTLAB_CARMEN_DATA (a folder of one's own copy of its logs) or in
/// ../shared/data/carmen; empty when in neither.
std::string benchmark_file(const std::string& name) {
  for (const char* dir :
       {static_cast<const char*>(std::getenv("DRIFTLAB_CARMEN_DATA")), DRIFTLAB_SHARED_DATA "/carmen"}) {
    if (dir != nullptr && std::filesystem::exists(std::string(dir) + "/" + name)) return std::string(dir) + "/" + name;
  }
  return "";
}

/// The stamps of a log's scans, in the log's order.
std::vector<int64_t> scan_stamps(const std::string& lcm) {
  std::vector<int64_t> stamps;
  for (const auto& e : test::read_all(lcm)) {
    if (e.channel == "/scan") stamps.push_back(test::decode<laser_scan_t>(e).header.utime);
  }
  return stamps;
}

/// Writes `relations` (on the stamps of `from`'s scans) to `out` with each stamp replaced by the stamp of the scan
/// of `to` in the same place of its log's order; every other field as it was.
void restamp_relations(const std::string& relations, const std::string& from, const std::string& to,
                       const std::string& out) {
  const std::vector<int64_t> old_stamps = scan_stamps(from), new_stamps = scan_stamps(to);
  ASSERT_EQ(old_stamps.size(), new_stamps.size()) << from << " and " << to << " have different scans";
  std::map<int64_t, int64_t> stamp_of;  // old stamp -> new stamp
  for (size_t i = 0; i < old_stamps.size(); ++i) stamp_of.emplace(old_stamps[i], new_stamps[i]);
  std::ifstream in(relations);
  std::ofstream restamped(out);
  std::string line;
  size_t lines = 0;
  while (std::getline(in, line)) {
    double t[2];
    int used = 0;
    if (line.empty() || line[0] == '#' || std::sscanf(line.c_str(), "%lf %lf%n", &t[0], &t[1], &used) != 2) continue;
    char stamps[64];
    int64_t s[2];
    for (int k = 0; k < 2; ++k) {
      // The relations' stamps have microseconds; the scan of each is the one within 50 us of it.
      const auto at = stamp_of.lower_bound(std::llround(t[k] * 1e6) - 50);
      ASSERT_TRUE(at != stamp_of.end() && std::abs(at->first - std::llround(t[k] * 1e6)) <= 50)
          << relations << ": no scan of " << from << " at " << t[k];
      s[k] = at->second;
    }
    std::snprintf(stamps, sizeof(stamps), "%.6f %.6f", static_cast<double>(s[0]) * 1e-6,
                  static_cast<double>(s[1]) * 1e-6);
    restamped << stamps << line.substr(static_cast<size_t>(used)) << "\n";
    ++lines;
  }
  ASSERT_GT(lines, 1000u);
}

TEST_P(SlamOnMoreLogs, ClosesLoopsWithoutFoldingTheMap) {
  const MoreLog& run = GetParam();
  const std::string log = benchmark_file(run.log);
  std::string relations = benchmark_file(run.relations);
  const std::string stamped = *run.stamps_of == 0 ? log : benchmark_file(run.stamps_of);
  if (log.empty() || relations.empty() || stamped.empty()) {
    GTEST_SKIP() << "not in ../shared/data/carmen yet: " << run.log << " " << run.stamps_of;
  }
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + log + " -o " + dir.file("raw.lcm") + " >/dev/null"), 0);
  if (*run.stamps_of != 0) {
    ASSERT_EQ(
        test::run(test::kDriftlabProgram + " import " + stamped + " -o " + dir.file("stamped.lcm") + " >/dev/null"), 0);
    ASSERT_NO_FATAL_FAILURE(
        restamp_relations(relations, dir.file("stamped.lcm"), dir.file("raw.lcm"), dir.file("restamped.relations")));
    relations = dir.file("restamped.relations");
  }
  std::string config;
  if (*run.settings != 0) {
    std::ofstream(dir.file("slam.yaml")) << "slam:\n  2d: " << run.settings << "\n";
    config = " --config " + dir.file("slam.yaml");
  }
  const auto replay = test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --json" + config + " -o " +
                                          dir.file("slam.lcm"));
  const auto& warnings = replay["modules"][0]["warnings"];
  if (*run.warning == 0) {
    EXPECT_TRUE(warnings.empty()) << warnings;
  } else {
    ASSERT_EQ(warnings.size(), 1u) << warnings;
    EXPECT_NE(warnings[0].get<std::string>().find(run.warning), std::string::npos) << warnings;
  }
  test::check_loop_records(dir.file("slam.lcm"), replay["modules"][0]["metrics"]);
  const auto error = test::relation_error(dir.file("slam.lcm") + ":SLAM_TRAJECTORY", relations);
  const double mean = error["trans_m"]["mean"].get<double>(), max = error["trans_m"]["max"].get<double>();
  std::printf("%s: relation error %.4f m, max %.3f m over %zu relations\n", run.name, mean, max,
              error["used"].get<size_t>());
  EXPECT_GT(error["used"].get<size_t>(), 1000u);
  EXPECT_LT(mean, 0.10);
  EXPECT_LT(max, 1.5);
  if (*run.row != 0) test::expect_benchmark_row(run.row, replay["modules"][0]["metrics"], error);
  if (*run.label == 0) return;
  test::expect_heading_rows(run.label, replay["modules"][0]["metrics"]);
  // With the odometry in every match (auto leaves it out here) the front end, pulled towards the odometry between
  // matches, drifts beyond the loop searches' reach: ours 1.57 m on Freiburg 079, 1.19 m on MIT CSAIL.
  EXPECT_GT(expect_match_odometry_row(run.label, dir, dir.file("raw.lcm"), relations), 0.10);
}

INSTANTIATE_TEST_SUITE_P(
    Carmen, SlamOnMoreLogs,
    ::testing::Values(
        MoreLog{"fr079", "fr079.orig.bag", "fr079.relations", "", "", "Freiburg 079 (bag)", "Freiburg 079"},
        MoreLog{"mit_csail", "mit-csail.orig.bag", "mit-csail.relations", "", "", "MIT CSAIL (bag)", "MIT CSAIL"},
        MoreLog{"mit_csail_clf", "mit-csail.clf", "mit-csail.relations", "", "", "MIT CSAIL (`.clf`)"},
        // Folded (2.03 m) until a far search whose best pose lay near its window's edge searched again in a wider
        // one: with one point in 3 the front end drifts further, the place was just beyond the window, and a door
        // 1.7 m down the corridor inside it was taken (and confirmed).
        MoreLog{"mit_csail_decimation_3", "mit-csail.orig.bag", "mit-csail.relations", "{decimation: 3}"},
        // ricoslam's bags "sorted" (each message written at its stamp, header.seq in that order): the same
        // messages, another order of those that share a stamp, so another draw of each log (Intel 0.032 m, max
        // 0.74 m; ACES, Freiburg 079 and MIT CSAIL as their original bags to a millimetre).
        MoreLog{"intel_sorted", "intel.sort.bag", "intel.relations"},
        MoreLog{"aces_sorted", "aces.sort.bag", "aces.relations"},
        MoreLog{"fr079_sorted", "fr079.sort.bag", "fr079.relations"},
        MoreLog{"mit_csail_sorted", "mit-csail.sort.bag", "mit-csail.relations"},
        // ricoslam's bags made by its clf2bag.py (as MIT Killian's, SlamOnKillian): the same scans, scan i stamped
        // 1e9 s + i / 10 s and one odometry message per scan (Intel's and Freiburg 079's original bags have 1.8-2),
        // so the relations are put on them through the original bag's scans. Intel 0.032 m (max 0.28 m), ACES 0.046
        // m (max 0.69 m), Freiburg 079 0.061 m (max 0.24 m), MIT CSAIL as its original bag (the clinic too, 2.14 m).
        MoreLog{"intel_clf2bag", "intel.clf2bag.bag", "intel.relations", "", "", "", "", "intel.orig.bag"},
        MoreLog{"aces_clf2bag", "aces.clf2bag.bag", "aces.relations", "", "", "", "", "aces.orig.bag"},
        MoreLog{"fr079_clf2bag", "fr079.clf2bag.bag", "fr079.relations", "", "", "", "", "fr079.orig.bag"},
        MoreLog{"mit_csail_clf2bag", "mit-csail.clf2bag.bag", "mit-csail.relations", "", "", "", "",
                "mit-csail.orig.bag"},
        // Its FLASER lines do not say the scanner's maximum, and its longest reading (51.22 m) occurs once: the
        // module finds the no-return code (51.06 m) itself and says so (SlamOnKillian).
        MoreLog{"mit_killian_clf", "mit-killian.clf", "mit-killian.relations", "", "are the scanner's no-return code"}),
    [](const auto& info) { return std::string(info.param.name); });

// MIT Killian Court (17,480 scans over 2 h 8 min, 1.5 km through MIT's corridors), as INESC TEC's ricoslam made a ROS
// bag of it: its converter (clf2bag.py) gave scan i the stamp 1e9 s + i / 10 s, so the benchmark's relations, on the
// CARMEN log's stamps, need the same renumbering. The log's scans came every 0.439 s (each gap between two relation
// stamps is a whole number of that period to within 0.2 of it): a relation stamp is scan `first + the periods since
// the first stamp`, and `first` is where the wheel odometry turns as the relations do (over the relations a few
// seconds long, whose turn the odometry measures to a degree). The renumbered relations score the bag as the
// original would the .clf. Killian's scanner answers 51.05-51.12 m for a beam without an echo while the bag says
// range_max 80 m: found by the module (no_return_test.cc), the relation error is 0.057 m (max 1.41 m; with an 8 m
// loop reach, 0.055 m and 1.11 m, but 2 of scripts/slam-robustness's 10 runs met the bar instead of 6); with those
// readings taken for walls 3.8 m (36 m), the front end dragged along the corridors by points 51 m ahead.
/// Imports Killian's bag to `raw` and writes its relations renumbered onto the bag's scans to `restamped` (above).
void import_killian(const std::string& bag, const std::string& relations, const std::string& raw,
                    const std::string& restamped) {
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + bag + " -o " + raw + " >/dev/null"), 0);
  std::vector<int64_t> stamps;                  // the bag's scans, in order
  std::vector<std::array<double, 3>> odometry;  // at each scan's stamp (the bag has one per scan)
  for (const auto& e : test::read_all(raw)) {
    if (e.channel == "/scan") stamps.push_back(test::decode<driftlab::laser_scan_t>(e).header.utime);
    if (e.channel == "/odom") {
      const auto o = test::decode<driftlab::odometry_t>(e);
      odometry.push_back({o.position.x, o.position.y, 2 * std::atan2(o.orientation.z, o.orientation.w)});
    }
  }
  ASSERT_EQ(stamps.size(), 17480u);
  ASSERT_EQ(odometry.size(), stamps.size());
  auto rel = analyzers::load_relations(relations);
  ASSERT_TRUE(rel) << rel.error().message;
  std::vector<double> times;
  for (const auto& r : *rel) times.push_back(r.t1), times.push_back(r.t2);
  // A relation's roll, pitch and yaw (the file's order; R = Rz(yaw) Ry(pitch) Rx(roll)).
  auto rpy = [](const analyzers::Relation& r) {
    const Eigen::Matrix3d m = r.rotation.toRotationMatrix();
    return Eigen::Vector3d(std::atan2(m(2, 1), m(2, 2)), std::asin(-m(2, 0)), std::atan2(m(1, 0), m(0, 0)));
  };
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  // The period: from the shortest gap, refined over all of them (each a whole number of periods).
  double period = times[1] - times[0];
  for (size_t k = 1; k < times.size(); ++k) period = std::min(period, times[k] - times[k - 1]);
  for (int round = 0; round < 5; ++round) {
    double periods = 0;
    for (size_t k = 1; k < times.size(); ++k) periods += std::round((times[k] - times[k - 1]) / period);
    period = (times.back() - times.front()) / periods;
  }
  std::map<double, int64_t> index;  // relation stamp -> periods since the first
  int64_t n = 0;
  index[times[0]] = 0;
  for (size_t k = 1; k < times.size(); ++k) {
    const double periods = (times[k] - times[k - 1]) / period;
    ASSERT_LT(std::abs(periods - std::round(periods)), 0.2) << "gap " << times[k] - times[k - 1] << " s";
    index[times[k]] = n += std::llround(periods);
  }
  std::printf("mit_killian: scans every %.4f s; the relations span %lld of them\n", period, static_cast<long long>(n));
  ASSERT_LT(n, static_cast<int64_t>(stamps.size()));
  // The first relation stamp's scan: where the odometry's turns agree with the relations'.
  auto turn_error = [&](int64_t first) {
    double sum = 0;
    int count = 0;
    for (const auto& r : *rel) {
      if (std::abs(r.t2 - r.t1) > 5) continue;
      const auto& a = odometry[static_cast<size_t>(first + index[r.t1])];
      const auto& b = odometry[static_cast<size_t>(first + index[r.t2])];
      sum += std::abs(std::remainder(b[2] - a[2] - rpy(r)[2], 2 * M_PI)), ++count;
    }
    return sum / count;
  };
  int64_t first = 0;
  for (int64_t f = 1; f + n < static_cast<int64_t>(stamps.size()); ++f) {
    if (turn_error(f) < turn_error(first)) first = f;
  }
  std::printf(
      "mit_killian: the first relation stamp is scan %lld (odometry's turns off by %.2f deg on average; "
      "%.2f and %.2f one scan either side)\n",
      static_cast<long long>(first), turn_error(first) * 180 / M_PI, turn_error(first - 1) * 180 / M_PI,
      turn_error(first + 1) * 180 / M_PI);
  EXPECT_LT(turn_error(first), 1.0 * M_PI / 180);  // the odometry turns as the relations do, to a degree
  std::ofstream out(restamped);
  for (const auto& r : *rel) {
    const Eigen::Vector3d angles = rpy(r);
    char line[200];
    std::snprintf(line, sizeof(line), "%.6f %.6f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                  static_cast<double>(stamps[static_cast<size_t>(first + index[r.t1])]) * 1e-6,
                  static_cast<double>(stamps[static_cast<size_t>(first + index[r.t2])]) * 1e-6, r.translation.x(),
                  r.translation.y(), r.translation.z(), angles[0], angles[1], angles[2]);
    out << line;
  }
}

TEST(SlamOnKillian, TheRicoslamBagWithTheRelationsOnItsStamps) {
  const std::string bag = benchmark_file("mit-killian.clf2bag.bag");
  const std::string relations = benchmark_file("mit-killian.relations");
  if (bag.empty() || relations.empty()) GTEST_SKIP() << "not in ../shared/data/carmen yet: mit-killian.clf2bag.bag";
  test::TempDir dir;
  const std::string restamped = dir.file("killian.relations");
  ASSERT_NO_FATAL_FAILURE(import_killian(bag, relations, dir.file("raw.lcm"), restamped));
  const auto rel = analyzers::load_relations(relations);
  ASSERT_TRUE(rel) << rel.error().message;
  const auto replay =
      test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --json -o " + dir.file("slam.lcm"));
  const auto& warnings = replay["modules"][0]["warnings"];
  ASSERT_EQ(warnings.size(), 1u) << warnings;
  EXPECT_NE(warnings[0].get<std::string>().find("are the scanner's no-return code"), std::string::npos) << warnings;
  test::check_loop_records(dir.file("slam.lcm"), replay["modules"][0]["metrics"]);
  const auto error = test::relation_error(dir.file("slam.lcm") + ":SLAM_TRAJECTORY", restamped);
  const double mean = error["trans_m"]["mean"].get<double>(), max = error["trans_m"]["max"].get<double>();
  std::printf("mit_killian: relation error %.4f m, max %.3f m over %zu relations\n", mean, max,
              error["used"].get<size_t>());
  EXPECT_EQ(error["used"].get<size_t>(), rel->size());
  EXPECT_LT(mean, 0.10);
  EXPECT_LT(max, 1.5);
  test::expect_benchmark_row("MIT Killian Court (bag)", replay["modules"][0]["metrics"], error);
  test::expect_heading_rows("MIT Killian Court", replay["modules"][0]["metrics"]);
  // With the odometry in every match its scans' turns (0.88 of the odometry's) and its odometry's bend the
  // Infinite Corridor's passes against each other: ours 8.72 m.
  EXPECT_GT(expect_match_odometry_row("MIT Killian Court", dir, dir.file("raw.lcm"), restamped), 0.10);

  // From 15 s in: a far test at 619 s matches a lookalike stretch of corridor where the drifted estimate puts the
  // robot and ties it, alone, to the first keyframe; the return confirmed at 644 s puts that place metres away,
  // and with both in, the graph bends the first keyframes to keep them. Left out at the end, the rest of the graph
  // puts it metres from what it measured, where a closure alone moves the estimate 0.5 m at most: undone.
  const auto later = test::driftlab_json("replay " + dir.file("raw.lcm") + " --start 15 --modules slam --json -o " +
                                         dir.file("later.lcm"));
  test::check_loop_records(dir.file("later.lcm"), later["modules"][0]["metrics"]);
  double off = 0, off_deg = 0;  // how far the rest of the graph puts the closure to the first keyframe
  for (const auto& e : test::read_all(dir.file("later.lcm"))) {
    if (e.channel != "SLAM_LOOPS") continue;
    const auto r = test::decode<driftlab::loop_closure_t>(e);
    const std::string said = "the graph without it is ";
    const size_t at = r.reason.find(said);
    if (r.outcome != "undone" || r.old_keyframe != 0 || at == std::string::npos) continue;
    ASSERT_EQ(std::sscanf(r.reason.c_str() + at + said.size(), "%lf m and %lf deg", &off, &off_deg), 2) << r.reason;
  }
  const auto later_error = test::relation_error(dir.file("later.lcm") + ":SLAM_TRAJECTORY", restamped);
  std::printf(
      "mit_killian from 15 s: the closure to the first keyframe undone, %.2f m and %.1f deg off; relation "
      "error %.4f m, max %.3f m\n",
      off, off_deg, later_error["trans_m"]["mean"].get<double>(), later_error["trans_m"]["max"].get<double>());
  EXPECT_GT(off, 2.0);  // metres: what a wrong match in a corridor is off by, not a right one's few tenths
  test::expect_doc_text_figures("docs/slam.md", "MIT Killian Court from 15 s", "Judged by chi2",
                                {NAN, NAN, off, off_deg, later_error["trans_m"]["mean"].get<double>(),
                                 later_error["trans_m"]["max"].get<double>()});
}

double yaw_of(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d m = q.toRotationMatrix();
  return std::atan2(m(1, 0), m(0, 0));
}

/// Each pose of a channel (analyzers::load_log_channel: pose_t or odometry_t) by stamp [us]: x, y, yaw.
using Poses2d = std::map<int64_t, std::array<double, 3>>;
Poses2d poses_on(const std::string& log, const std::string& channel) {
  const auto t = analyzers::load_log_channel(log, channel);
  EXPECT_TRUE(t) << t.error().message;
  Poses2d out;
  for (size_t i = 0; t && i < t->size(); ++i) {
    out[std::llround(t->stamps[i] * 1e6)] = {t->positions[i].x(), t->positions[i].y(), yaw_of(t->orientations[i])};
  }
  return out;
}

/// The pose stamped within 100 us of t [s] (relations files round their stamps to the microsecond), or null.
const std::array<double, 3>* pose_at(const Poses2d& poses, double t) {
  const auto us = static_cast<int64_t>(std::llround(t * 1e6));
  const auto it = poses.lower_bound(us - 100);
  return it == poses.end() || it->first > us + 100 ? nullptr : &it->second;
}

/// b seen from a (x, y, yaw).
std::array<double, 3> seen_from(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  const double c = std::cos(a[2]), s = std::sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
  return {c * dx + s * dy, -s * dx + c * dy, std::remainder(b[2] - a[2], 2 * M_PI)};
}

/// Each scan's points in the robot's frame (the scanner's mounting from /tf_static applied), by stamp [us].
using Scans2d = std::map<int64_t, std::vector<std::array<double, 2>>>;
Scans2d scans_on(const std::string& log) {
  std::map<std::string, std::array<double, 3>> mounting;  // frame -> x, y, yaw in the robot's frame
  std::vector<driftlab::laser_scan_t> scans;
  for (const auto& e : test::read_all(log)) {
    if (e.channel == "/tf_static") {
      for (const auto& t : test::decode<driftlab::tf_t>(e).transforms) {
        mounting[t.child_frame_id] = {t.translation.x, t.translation.y, 2 * std::atan2(t.rotation.z, t.rotation.w)};
      }
    } else if (e.channel == "/scan") {
      scans.push_back(test::decode<driftlab::laser_scan_t>(e));
    }
  }
  Scans2d out;
  for (const auto& s : scans) {
    const auto m = mounting.count(s.header.frame_id) ? mounting[s.header.frame_id] : std::array<double, 3>{};
    auto& points = out[s.header.utime];
    for (int i = 0; i < s.nranges; ++i) {
      const double r = s.ranges[static_cast<size_t>(i)], a = m[2] + s.angle_min + i * s.angle_increment;
      if (std::isfinite(r) && r > s.range_min && r < s.range_max) {
        points.push_back({m[0] + r * std::cos(a), m[1] + r * std::sin(a)});
      }
    }
  }
  return out;
}

/// The place around scan `at` [us]: the points of every scan within `window` [s] of it, put where `poses` puts
/// them, in the frame of the robot at `at`.
std::vector<std::array<double, 2>> place_around(const Scans2d& scans, const Poses2d& poses, int64_t at, double window) {
  std::vector<std::array<double, 2>> out;
  const auto& origin = poses.at(at);
  const auto span = static_cast<int64_t>(window * 1e6);
  for (auto it = poses.lower_bound(at - span); it != poses.end() && it->first <= at + span; ++it) {
    const auto scan = scans.find(it->first);
    if (scan == scans.end()) continue;
    const auto p = seen_from(origin, it->second);
    const double c = std::cos(p[2]), s = std::sin(p[2]);
    for (const auto& q : scan->second) out.push_back({p[0] + c * q[0] - s * q[1], p[1] + s * q[0] + c * q[1]});
  }
  return out;
}

constexpr double kPlaceWindow = 15;        // [s]: a place is the scans within this of one
constexpr double kOverlapDistance = 0.15;  // [m]: as the loop test counts overlap (slam.2d.loop_match_distance)

/// The share of `b`'s points (b's frame put at `pose` in a's) with a point of `a` within `distance` [m].
double overlap(const std::vector<std::array<double, 2>>& a, const std::vector<std::array<double, 2>>& b,
               const std::array<double, 3>& pose, double distance) {
  std::map<std::pair<int64_t, int64_t>, std::vector<std::array<double, 2>>> cells;  // cells of `distance`
  auto cell = [&](double v) { return static_cast<int64_t>(std::floor(v / distance)); };
  for (const auto& p : a) cells[{cell(p[0]), cell(p[1])}].push_back(p);
  const double c = std::cos(pose[2]), s = std::sin(pose[2]);
  size_t close = 0;
  for (const auto& q : b) {
    const double x = pose[0] + c * q[0] - s * q[1], y = pose[1] + s * q[0] + c * q[1];
    bool found = false;
    for (int64_t i = cell(x) - 1; i <= cell(x) + 1 && !found; ++i) {
      for (int64_t j = cell(y) - 1; j <= cell(y) + 1 && !found; ++j) {
        const auto it = cells.find({i, j});
        if (it == cells.end()) continue;
        for (const auto& p : it->second) found |= std::hypot(p[0] - x, p[1] - y) < distance;
      }
    }
    close += found ? 1 : 0;
  }
  return b.empty() ? 0.0 : static_cast<double>(close) / static_cast<double>(b.size());
}

// slam.2d.match_odometry weighs the odometry's prediction into each scan match by the information of each (the
// front end slides along featureless corridors where good wheel odometry holds; docs/slam.md, "Odometry in the
// match"). Not on ACES and Intel by default (auto decides it off: SlamOnTheBenchmark): on Intel, its front end
// pulled towards its odometry, it folds the map (5.4 m). On ACES with it set true it is weighed into every matched scan
// and the log still meets the bar (ours: 0.038 m, max 0.41 m; 0.048 m and 0.78 m without it).
TEST(SlamMatchOdometry, OnAcesEveryMatchWeighsItInAndTheBarHolds) {
  const auto files = test::carmen_run("aces");
  if (files.empty()) return;
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + dir.file("raw.lcm") + " >/dev/null"),
            0);
  std::ofstream(dir.file("slam.yaml")) << "slam:\n  2d: {match_odometry: true}\n";
  const auto replay = test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --config " +
                                          dir.file("slam.yaml") + " --json -o " + dir.file("slam.lcm"));
  const auto& metrics = replay["modules"][0]["metrics"];
  const double scans = metrics["scans"].get<double>(), still = metrics["scans_still"].get<double>();
  // Every scan matched (ACES has no unmatched ones) with the odometry weighed in; the first has no prediction.
  EXPECT_EQ(metrics["unmatched"].get<double>(), 0);
  EXPECT_EQ(metrics["scans_weighed"].get<double>(), scans - still - 1) << metrics;
  test::check_loop_records(dir.file("slam.lcm"), metrics);
  // Its odometry's heading is further from the matches than the noise model says (SlamOnTheBenchmark), and the
  // one warning says so; here the map holds all the same, as the warning's "may" allows.
  EXPECT_GT(metrics["odometry_heading_q90"].get<double>(), 2.0);
  const auto& warnings = replay["modules"][0]["warnings"];
  ASSERT_EQ(warnings.size(), 1u) << warnings;
  EXPECT_NE(warnings[0].get<std::string>().find("the odometry's heading disagrees with the scan matches"),
            std::string::npos)
      << warnings;
  const auto error = test::relation_error(dir.file("slam.lcm") + ":SLAM_TRAJECTORY", files.relations);
  const double mean = error["trans_m"]["mean"].get<double>(), max = error["trans_m"]["max"].get<double>();
  std::printf("aces with match_odometry: relation error %.4f m, max %.3f m\n", mean, max);
  EXPECT_LT(mean, 0.10);
  EXPECT_LT(max, 1.5);
  test::expect_run_row("### Odometry in the match", "ACES", 1, metrics, error);
}

// Not on Intel: its odometry's heading is further from its matches than ACES's (SlamOnTheBenchmark; auto leaves it
// out), and with it in every match the front end, pulled towards that odometry between matches, drifts beyond the
// loop searches' reach and the map folds (ours: 5.68 m, max 35.6 m, 4 loop closures where the defaults keep 558).
// The reason auto decides by the odometry's heading, and the figures docs/slam.md shows.
TEST(SlamMatchOdometry, OnIntelTheFrontEndPulledToItsOdometryFoldsTheMap) {
  const auto files = test::carmen_run("intel");
  if (files.empty()) return;
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + dir.file("raw.lcm") + " >/dev/null"),
            0);
  EXPECT_GT(expect_match_odometry_row("Intel", dir, dir.file("raw.lcm"), files.relations), 1.0);
}

// slam.2d.loop_rescue_near (off by default): a near loop test whose ICP was pulled beyond its reach searches its
// window as a far test does. On Intel with max_iterations 40 (a scripts/slam-robustness run) the near tests' ICP
// leaves the reach dozens of times, where the place mostly lay within centimetres of the estimate. The test wants
// near-far records, some accepted, each counted once as a loop test, and none without the setting. Until
// 2026-12-06 the rescue also made this run meet the bar (0.032 m, max 0.65 m, against 0.143 m, max 2.14 m);
// since the module matches Intel's scans in stamp order the run meets it without the rescue (0.033 m, max 0.80 m)
// and misses its largest error with it (ours: 0.041 m, max 2.21 m): one closure more moves which later ones go in,
// as on MIT Killian (docs/slam.md, "How robust"), and the setting stays off.
TEST(SlamRescueNear, OnIntelWithFortyIterationsTheRescuedTestsCloseLoops) {
  const auto files = test::carmen_run("intel");
  if (files.empty()) return;
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + files.bag + " -o " + dir.file("raw.lcm") + " >/dev/null"),
            0);
  std::map<std::string, std::map<std::string, int>> searches;  // setting -> search -> outcome "accepted" or any
  for (const std::string rescue : {"false", "true"}) {
    std::ofstream(dir.file(rescue + ".yaml"))
        << "slam:\n  2d: {max_iterations: 40, loop_rescue_near: " << rescue << "}\n";
    const std::string out = dir.file(rescue + ".lcm");
    const auto replay = test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --config " +
                                            dir.file(rescue + ".yaml") + " --json -o " + out);
    test::check_loop_records(out, replay["modules"][0]["metrics"]);
    for (const auto& e : test::read_all(out)) {
      if (e.channel != "SLAM_LOOPS") continue;
      const auto r = test::decode<driftlab::loop_closure_t>(e);
      ++searches[rescue][r.search];
      if (r.outcome == "accepted") ++searches[rescue][r.search + " accepted"];
      if (r.search == "near-far") {
        EXPECT_LE(r.radius_m, 2.5) << "a near test's reach";
      }
    }
    const auto error = test::relation_error(out + ":SLAM_TRAJECTORY", files.relations);
    std::printf("intel, max_iterations 40, loop_rescue_near %s: relation error %.4f m, max %.3f m\n", rescue.c_str(),
                error["trans_m"]["mean"].get<double>(), error["trans_m"]["max"].get<double>());
  }
  EXPECT_EQ(searches["false"].count("near-far"), 0u);
  EXPECT_GT(searches["true"]["near-far"], 10);
  EXPECT_GT(searches["true"]["near-far accepted"], 5);
}

// slam.2d.loop_seen_only (off by default): a near loop test's ICP takes only the current points one of the old place's
// scans could have seen (seen_points, scan_graph_test.cc). Where a corridor was passed the other way, the current
// scans see ahead what the old ones did not, and those points, paired with the old place's nearest, pull the match
// along the corridor. docs/slam.md's table "What an old place saw" holds each log's run with it; Intel and ACES run
// in CI, the other four with their files ($DRIFTLAB_CARMEN_DATA or ../shared/data/carmen). The bar is the issue's
// (0.10 m, 1.5 m) on every log but the clinic, whose reference gets its largest relations wrong (below) and whose
// mean lies at the bar either way (0.099 m with the defaults); the rows are the code's figures.
TEST(SlamSeenOnly, EveryLogWithTheNearTestsOnWhatTheOldPlaceSaw) {
  test::TempDir dir;
  std::ofstream(dir.file("seen.yaml")) << "slam:\n  2d: {loop_seen_only: true}\n";
  const auto run = [&](const std::string& name, const std::string& log, const std::string& relations,
                       const std::string& label, bool bar) {
    const std::string raw = dir.file(name + ".lcm"), out = dir.file(name + "-slam.lcm");
    if (!std::filesystem::exists(raw)) {
      ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + log + " -o " + raw + " >/dev/null"), 0);
    }
    const auto replay = test::driftlab_json("replay " + raw + " --modules slam --config " + dir.file("seen.yaml") +
                                            " --json -o " + out);
    test::check_loop_records(out, replay["modules"][0]["metrics"]);
    const auto error = test::relation_error(out + ":SLAM_TRAJECTORY", relations);
    const double mean = error["trans_m"]["mean"].get<double>(), max = error["trans_m"]["max"].get<double>();
    std::printf("%s, loop_seen_only: relation error %.4f m, max %.3f m\n", name.c_str(), mean, max);
    if (bar) {
      EXPECT_LT(mean, 0.10) << name;
      EXPECT_LT(max, 1.5) << name;
    }
    test::expect_run_row("**What an old place saw", label, 1, replay["modules"][0]["metrics"], error);
  };
  for (const std::string name : {"intel", "aces"}) {
    const auto files = test::carmen_run(name);
    if (files.empty()) return;
    run(name, files.bag, files.relations, name == "intel" ? "Intel" : "ACES", true);
  }
  const std::vector<std::array<std::string, 3>> more = {
      {"fr079.orig.bag", "fr079.relations", "Freiburg 079"},
      {"mit-csail.orig.bag", "mit-csail.relations", "MIT CSAIL"},
      {"fr-clinic_robotlaser.orig.bag", "fr-clinic.relations", "Freiburg clinic"}};
  for (const auto& [log, relations, label] : more) {
    if (benchmark_file(log).empty() || benchmark_file(relations).empty()) continue;
    run(log.substr(0, log.find('.')), benchmark_file(log), benchmark_file(relations), label,
        label != "Freiburg clinic");
  }
  const std::string bag = benchmark_file("mit-killian.clf2bag.bag"),
                    relations = benchmark_file("mit-killian.relations");
  if (bag.empty() || relations.empty()) return;
  ASSERT_NO_FATAL_FAILURE(import_killian(bag, relations, dir.file("killian.lcm"), dir.file("killian.relations")));
  run("killian", bag, dir.file("killian.relations"), "MIT Killian Court", true);
}

// The Freiburg clinic (6,917 scans over 80 minutes of a hospital's corridors, at 1.4 Hz; its files as for
// SlamOnMoreLogs, skipped until they are in ../shared/data/carmen). Without the odometry in the match
// (match_odometry false) it folds (2.52 m, max 73 m): ICP slides along corridors where the wheel odometry holds,
// and the return after 4,400 s is 62 m off, beyond any loop search. With it, which the defaults (auto) turn on
// here, the mean is under the bar (ours: 0.099 m). It is not under its 1.5 m
// maximum, and this is why: every relation 1.5 m off or more (ours: 8, 1.6-2.1 m, all from 3,119-3,187 s to
// 3,346-3,356 s, where the robot came back turned 140-170 degrees) contradicts two witnesses.
// - The wheel odometry: each such relation turns 26-29 degrees otherwise than the odometry turns between the same
//   two scans, while ours turns within 1.1-3.1 degrees of it. The test wants the reference 10 degrees or more from
//   the odometry's turn and ours within 5 degrees of it (half of that, and twice what ours and the wheels differ
//   by). Ours weighs the odometry in, so this witness alone would not do; hence the second.
// - The scans, without the odometry: the places around the two scans (every scan within 15 s of each, put where
//   our trajectory puts it: over 30 s the front end's drift is centimetres) overlap 1-6% as the reference puts
//   them against each other and 9-30% as ours does (the share of the second place's points within 0.15 m of the
//   first's, as the loop test counts it). On the 71 loop relations (over 100 s apart) where ours is within 0.1 m of
//   the reference, the same measure gives the reference 0.59-1.36 of our overlap, median 0.99: it favours neither
//   when both are right. The test wants the reference's overlap under 10% and ours over 3 times it (between the
//   1.7 times the agreeing relations differ by at most and the 4.5 times of the closest far-off one), and the
//   control's median within 20% of 1.
TEST(SlamMatchOdometry, TheClinicMeetsTheMeanAndMissesOnlyWhereTheOdometryAndTheScansContradictItsReference) {
  const std::string bag = benchmark_file("fr-clinic_robotlaser.orig.bag");
  const std::string relations = benchmark_file("fr-clinic.relations");
  if (bag.empty() || relations.empty()) GTEST_SKIP() << "not in ../shared/data/carmen yet: fr-clinic_robotlaser";
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + bag + " -o " + dir.file("raw.lcm") + " >/dev/null"), 0);
  // The defaults: match_odometry auto turns itself on (ours: 1.60 over the first 600 checks; on at 2.2 or less).
  const auto replay =
      test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --json -o " + dir.file("slam.lcm"));
  test::check_loop_records(dir.file("slam.lcm"), replay["modules"][0]["metrics"]);
  EXPECT_EQ(replay["modules"][0]["metrics"]["match_odometry_auto"].get<double>(), 1);
  EXPECT_LE(replay["modules"][0]["metrics"]["match_odometry_auto_q90"].get<double>(), 2.2);
  // The one benchmark log whose wheel odometry turns as its noise model says (90% of the matches within 2.0 of
  // its standard deviations; ours 1.45), so no warning (with the defaults the figure is 1.77).
  EXPECT_LE(replay["modules"][0]["metrics"]["odometry_heading_q90"].get<double>(), 2.0);
  EXPECT_TRUE(replay["modules"][0]["warnings"].empty()) << replay["modules"][0]["warnings"];
  const auto error = test::relation_error(dir.file("slam.lcm") + ":SLAM_TRAJECTORY", relations);
  const double mean = error["trans_m"]["mean"].get<double>();
  std::printf("clinic: relation error %.4f m, max %.3f m over %zu relations\n", mean,
              error["trans_m"]["max"].get<double>(), error["used"].get<size_t>());
  EXPECT_EQ(error["used"].get<size_t>(), 2820u);
  EXPECT_LT(mean, 0.10);
  // With it off (the defaults until 2026-12-04) the map folds: ours 2.52 m, max 73.2 m.
  std::ofstream(dir.file("off.yaml")) << "slam:\n  2d: {match_odometry: false}\n";
  const auto off = test::driftlab_json("replay " + dir.file("raw.lcm") + " --modules slam --config " +
                                       dir.file("off.yaml") + " --json -o " + dir.file("off.lcm"));
  const auto off_error = test::relation_error(dir.file("off.lcm") + ":SLAM_TRAJECTORY", relations);
  EXPECT_GT(off_error["trans_m"]["mean"].get<double>(), 1.0);
  // The figures docs/slam.md shows: the table of every benchmark log (both runs), the table of the logs with the
  // odometry in the match (auto's run is the one `true` gives), and the odometry's heading with it on and off.
  const auto& metrics = replay["modules"][0]["metrics"];
  test::expect_benchmark_row("Freiburg clinic (bag)", metrics, error);
  test::expect_benchmark_row("Freiburg clinic (bag), `match_odometry: false`", off["modules"][0]["metrics"], off_error);
  test::expect_run_row("### Odometry in the match", "Freiburg clinic", 1, metrics, error);
  test::expect_heading_rows("Freiburg clinic", metrics,
                            {off["modules"][0]["metrics"]["odometry_heading_q90"].get<double>()});

  const Poses2d ours = poses_on(dir.file("slam.lcm"), "SLAM_TRAJECTORY"),
                odometry = poses_on(dir.file("raw.lcm"), "/odom");
  auto rel = analyzers::load_relations(relations);
  ASSERT_TRUE(rel) << rel.error().message;
  const Scans2d scans = scans_on(dir.file("raw.lcm"));
  const double start = static_cast<double>(odometry.begin()->first) * 1e-6;  // the log's first scan
  auto stamp = [&](double t) { return ours.lower_bound(std::llround(t * 1e6) - 100)->first; };
  int far_off = 0;
  std::vector<double> agreeing;  // control: reference's overlap over ours, on loop relations where the two agree
  // Where the mean comes from: the relation errors summed over the short relations (at most 30 s) and the long
  // ones, ours and the wheel odometry's alone. Over the short ones ours is within 15% of the wheels' (ours 1.08
  // times): it weighs them in where a scan is weak, and the front end without them was 0.081 m in median against
  // their 0.047 m. docs/slam.md shows the sums.
  std::array<double, 2> count{}, ours_sum{}, odometry_sum{};  // [0] short, [1] long
  for (const auto& r : *rel) {
    const auto *a = pose_at(ours, r.t1), *b = pose_at(ours, r.t2);
    const auto *oa = pose_at(odometry, r.t1), *ob = pose_at(odometry, r.t2);
    ASSERT_TRUE(a && b && oa && ob) << r.t1 << " " << r.t2;
    const auto step = seen_from(*a, *b), wheels = seen_from(*oa, *ob);
    const std::array<double, 3> reference = {r.translation.x(), r.translation.y(), yaw_of(r.rotation)};
    const double off = std::hypot(step[0] - reference[0], step[1] - reference[1]);
    const size_t span = r.t2 - r.t1 > 30 ? 1 : 0;
    count[span] += 1;
    ours_sum[span] += off;
    odometry_sum[span] += std::hypot(wheels[0] - reference[0], wheels[1] - reference[1]);
    const bool loop = r.t2 - r.t1 > 100;
    if (off < 1.5 && !(loop && off < 0.1)) continue;
    const auto first = place_around(scans, ours, stamp(r.t1), kPlaceWindow),
               second = place_around(scans, ours, stamp(r.t2), kPlaceWindow);
    const double ours_overlap = overlap(first, second, step, kOverlapDistance),
                 reference_overlap = overlap(first, second, reference, kOverlapDistance);
    if (off < 1.5) {
      agreeing.push_back(reference_overlap / ours_overlap);
      continue;
    }
    ++far_off;
    const double odometry_turn = wheels[2];
    const double reference_off = std::abs(std::remainder(reference[2] - odometry_turn, 2 * M_PI));
    const double ours_off = std::abs(std::remainder(step[2] - odometry_turn, 2 * M_PI));
    std::printf(
        "clinic: relation %.1f -> %.1f s: the reference turns %.1f deg from the odometry, ours %.1f; the places "
        "overlap %.0f%% as the reference puts them, %.0f%% as ours does\n",
        r.t1 - start, r.t2 - start, reference_off * 180 / M_PI, ours_off * 180 / M_PI, 100 * reference_overlap,
        100 * ours_overlap);
    EXPECT_GT(reference_off, 10 * M_PI / 180) << r.t1 << " " << r.t2;
    EXPECT_LT(ours_off, 5 * M_PI / 180) << r.t1 << " " << r.t2;
    EXPECT_LT(reference_overlap, 0.10) << r.t1 << " " << r.t2;
    EXPECT_GT(ours_overlap, 3 * reference_overlap) << r.t1 << " " << r.t2;
  }
  std::sort(agreeing.begin(), agreeing.end());
  ASSERT_FALSE(agreeing.empty());
  std::printf(
      "clinic: %zu loop relations within 0.1 m of ours: the reference's overlap over ours %.2f-%.2f, "
      "median %.2f\n",
      agreeing.size(), agreeing.front(), agreeing.back(), agreeing[agreeing.size() / 2]);
  EXPECT_GT(agreeing.size(), 50u);
  EXPECT_NEAR(agreeing[agreeing.size() / 2], 1.0, 0.2);
  EXPECT_GT(agreeing.front(), 1.0 / 3);  // no agreeing relation where ours overlaps 3 times the reference's
  EXPECT_LE(far_off, 20);  // a handful of relations, not a fold (the defaults: 115, up to 73 m off)
  std::printf(
      "clinic: relations' errors summed: %.0f short ones, ours %.1f m, the odometry's %.1f m; %.0f long ones, "
      "%.1f m and %.1f m\n",
      count[0], ours_sum[0], odometry_sum[0], count[1], ours_sum[1], odometry_sum[1]);
  EXPECT_LT(ours_sum[0], 1.15 * odometry_sum[0]);
  for (size_t k : {0, 1}) {
    const char* row = k == 0 ? "at most 30 s apart" : "longer";
    const std::string table = "| the clinic's relations |";
    test::expect_doc_figures("docs/slam.md", table, row, 1, {count[k]});
    test::expect_doc_figures("docs/slam.md", table, row, 2, {ours_sum[k]});
    test::expect_doc_figures("docs/slam.md", table, row, 3, {odometry_sum[k]});
  }
}

// The Freiburg clinic as the benchmark distributes it: a CARMEN log of ODOM and ROBOTLASER1 lines (ricoslam's
// parser counted 6,917 of each in it, and no FLASER), each ROBOTLASER1 line carrying its laser's pose and its
// robot's. That file is not in ricoslam's snapshot; this writes one of the same form from ricoslam's bag of it (each
// scan with the odometry of its stamp, the laser 0.22 m ahead of the robot as the bag's /tf_static says, no PARAM
// line), imports it as a .clf and replays it: the figures are the bag's, to their last digit (the row of docs/slam.md's
// table the bag's run fills). With the laser put on the robot's centre, as the importer did before it read the
// mounting from the lines, the relation error is over the bar's mean (ours: 0.104 m, max 2.44 m): a turn then
// moves the scans 0.22 m sideways where the odometry says the robot only turned. The benchmark's own file, where it is
// ($DRIFTLAB_CARMEN_DATA or ../shared/data/carmen), is held to the bar's mean (below).
TEST(SlamOnTheClinicsClf, ARobotlaserLogGivesTheBagsFigures) {
  const std::string bag = benchmark_file("fr-clinic_robotlaser.orig.bag");
  const std::string relations = benchmark_file("fr-clinic.relations");
  if (bag.empty() || relations.empty()) GTEST_SKIP() << "not in ../shared/data/carmen yet: fr-clinic_robotlaser";
  test::TempDir dir;
  ASSERT_EQ(test::run(test::kDriftlabProgram + " import " + bag + " -o " + dir.file("raw.lcm") + " >/dev/null"), 0);
  std::map<int64_t, driftlab::odometry_t> odometry;
  std::vector<driftlab::laser_scan_t> scans;
  double mount = 0;
  for (const auto& e : test::read_all(dir.file("raw.lcm"))) {
    if (e.channel == "/scan") scans.push_back(test::decode<driftlab::laser_scan_t>(e));
    if (e.channel == "/odom") {
      const auto o = test::decode<driftlab::odometry_t>(e);
      odometry[o.header.utime] = o;
    }
    if (e.channel == "/tf_static") mount = test::decode<driftlab::tf_t>(e).transforms.at(0).translation.x;
  }
  ASSERT_EQ(scans.size(), 6917u);
  ASSERT_NEAR(mount, 0.22, 1e-9);
  auto write_clf = [&](const std::string& path, const std::string& param, bool odom_lines = true) {
    std::ofstream out(path);
    out << "# CARMEN Logfile\n" << param;
    char buf[160];
    for (const auto& s : scans) {
      const auto it = odometry.find(s.header.utime);  // the bag has the odometry at each scan's stamp
      ASSERT_NE(it, odometry.end()) << s.header.utime;
      const auto& o = it->second;
      const double x = o.position.x, y = o.position.y, th = 2 * std::atan2(o.orientation.z, o.orientation.w);
      const double t = static_cast<double>(s.header.utime) * 1e-6, tv = o.linear_velocity.x, rv = o.angular_velocity.z;
      std::snprintf(buf, sizeof buf, "ODOM %.6f %.6f %.6f %.6f %.6f 0 %.6f clinic %.6f\n", x, y, th, tv, rv, t, t);
      if (odom_lines) out << buf;
      std::snprintf(buf, sizeof buf, "ROBOTLASER1 0 %.6f %.6f %.6f %.2f 0.01 0 %d", s.angle_min,
                    s.angle_max - s.angle_min, s.angle_increment, s.range_max, s.nranges);
      out << buf;
      for (const float r : s.ranges) {
        std::snprintf(buf, sizeof buf, " %.3f", r);
        out << buf;
      }
      std::snprintf(buf, sizeof buf, " 0 %.6f %.6f %.6f %.6f %.6f %.6f %.6f %.6f 0 0 0 %.6f clinic %.6f\n",
                    x + mount * std::cos(th), y + mount * std::sin(th), th, x, y, th, tv, rv, t, t);
      out << buf;
    }
  };
  // Imports and replays a .clf; returns the replay's metrics and the relation error. Ours give no warning (none of
  // a mounting missing); the benchmark's own file may say more of itself.
  auto run = [&](const std::string& clf, const std::string& name, bool ours = true) {
    EXPECT_EQ(test::run(test::kDriftlabProgram + " import " + clf + " -o " + dir.file(name + ".lcm") + " >/dev/null"),
              0);
    const auto replay = test::driftlab_json("replay " + dir.file(name + ".lcm") + " --modules slam --json -o " +
                                            dir.file(name + "-slam.lcm"));
    if (ours) EXPECT_TRUE(replay["modules"][0]["warnings"].empty()) << name << ": " << replay["modules"][0]["warnings"];
    const auto error = test::relation_error(dir.file(name + "-slam.lcm") + ":SLAM_TRAJECTORY", relations);
    std::printf("clinic %s: relation error %.4f m, max %.3f m\n", name.c_str(), error["trans_m"]["mean"].get<double>(),
                error["trans_m"]["max"].get<double>());
    return std::pair{replay["modules"][0]["metrics"], error};
  };
  ASSERT_NO_FATAL_FAILURE(write_clf(dir.file("clinic.clf"), ""));
  const auto [metrics, error] = run(dir.file("clinic.clf"), "clf");
  // The mounting came from the lines.
  for (const auto& e : test::read_all(dir.file("clf.lcm"))) {
    if (e.channel != "TF_STATIC") continue;
    const auto tf = test::decode<driftlab::tf_t>(e);
    ASSERT_EQ(tf.transforms.at(0).child_frame_id, "laser");
    EXPECT_NEAR(tf.transforms.at(0).translation.x, 0.22, 1e-6);
  }
  EXPECT_EQ(error["used"].get<size_t>(), 2820u);
  test::expect_benchmark_row("Freiburg clinic (bag)", metrics, error);

  ASSERT_NO_FATAL_FAILURE(write_clf(dir.file("centre.clf"), "PARAM robot_frontlaser_offset 0 nohost 0\n"));
  const auto centre = run(dir.file("centre.clf"), "centre").second;
  EXPECT_GT(centre["trans_m"]["mean"].get<double>(), 0.10);
  test::expect_doc_text_figures("docs/slam.md", "robot's centre, as before,", "From its ROBOTLASER1",
                                {centre["trans_m"]["mean"].get<double>(), centre["trans_m"]["max"].get<double>()});

  // Without its ODOM lines the odometry is the pose on the ROBOTLASER1 lines, the laser's (ROBOTLASER1_POSE, child
  // frame "laser"): the module takes the mounting off each (Slam2d.ASensorsPose...). Another draw of the same log
  // (the prior rides on its scan, without velocities): within 0.01 m of the bag's mean (ours: 0.102 m, 0.0035 m
  // above it); with the laser's pose taken as the robot's, 0.127 m.
  ASSERT_NO_FATAL_FAILURE(write_clf(dir.file("lines.clf"), "", false));
  const auto [lines_metrics, lines] = run(dir.file("lines.clf"), "lines");
  EXPECT_EQ(lines_metrics["odometry_of_sensor"].get<double>(), 6917);
  EXPECT_NEAR(lines["trans_m"]["mean"].get<double>(), error["trans_m"]["mean"].get<double>(), 0.01);
  test::expect_doc_text_figures("docs/slam.md", "takes that mounting off each and has the robot's",
                                "Its wheel odometry",
                                {lines["trans_m"]["mean"].get<double>(), lines["trans_m"]["max"].get<double>()});

  // ricoslam's sorted bag of it puts /tf_static just after the first scan (both at its stamp): the first scan
  // waits for its mounting (Slam2d.AScanBeforeItsMountingWaitsForIt), and the figures are the bag's again (with the
  // laser on the robot's centre for that scan alone: 0.103 m, max 2.09 m).
  if (const std::string sorted = benchmark_file("fr-clinic_robotlaser.sort.bag"); !sorted.empty()) {
    const auto [sorted_metrics, sorted_error] = run(sorted, "sorted");
    test::expect_benchmark_row("Freiburg clinic (bag)", sorted_metrics, sorted_error);
  }

  const std::string own = benchmark_file("fr-clinic_robotlaser.clf");
  if (own.empty()) return;
  // Its lines beside these (PARAM, other messages) and its odometry's own stamps make it another draw of the same
  // log: held to the bar's mean and to a largest error within 0.5 m of the bag's (that error is at the relations its
  // reference gets wrong, SlamMatchOdometry; a fold is metres).
  const auto own_error = run(own, "own", false).second;
  EXPECT_LT(own_error["trans_m"]["mean"].get<double>(), 0.10);
  EXPECT_NEAR(own_error["trans_m"]["max"].get<double>(), error["trans_m"]["max"].get<double>(), 0.5);
}

INSTANTIATE_TEST_SUITE_P(Carmen, SlamOnTheBenchmark,
                         ::testing::Values(Dataset{"intel", 2984, "Intel", "Intel (13,631 scans, 2,691 s)"},
                                           Dataset{"aces", 1279, "ACES", "ACES (7,374 scans, 1,366 s)"}),
                         [](const auto& info) { return std::string(info.param.name); });

// docs/slam.md's table "How robust": scripts/slam-robustness's ten runs of each benchmark log not in ../shared
// (Freiburg 079, MIT CSAIL, the clinic, Killian's bag with its relations renumbered), each row checked against them:
// the runs that meet the bar, and for each that fails, the figure of its label (the start, the setting) with its mean
// and largest relation error, in the script's order. 40 replays, about 10 minutes on two cores (the clinic's 50 s
// each): more than CI can spend once the logs are in ../shared, so this runs only on one's own copy of them
// ($DRIFTLAB_CARMEN_DATA, a deliberate run), and is skipped otherwise. Intel's and ACES's rows are
// docs/tutorial-public-dataset.md's block, which the doc test runs.
TEST(SlamRobustness, TheTableOfTheLogsNotInShared) {
  const char* own = std::getenv("DRIFTLAB_CARMEN_DATA");
  if (own == nullptr) GTEST_SKIP() << "runs only with $DRIFTLAB_CARMEN_DATA (40 replays, about 10 minutes)";
  const std::string data = own;
  // Each log and its relations, as slam-robustness takes them (Killian's bag and relations are renumbered first).
  const std::vector<std::pair<std::string, std::string>> logs = {
      {"fr079.orig.bag", "fr079.relations"},
      {"mit-csail.orig.bag", "mit-csail.relations"},
      {"fr-clinic_robotlaser.orig.bag", "fr-clinic.relations"},
      {"mit-killian.clf2bag.bag", "mit-killian.relations"}};
  for (const auto& [log, relations] : logs) {
    for (const auto& f : {log, relations}) {
      if (!std::filesystem::exists(data + "/" + f)) GTEST_SKIP() << "not in $DRIFTLAB_CARMEN_DATA: " << f;
    }
  }
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(import_killian(data + "/mit-killian.clf2bag.bag", data + "/mit-killian.relations",
                                         dir.file("mit-killian.lcm"), dir.file("killian.relations")));
  std::string specs;
  for (size_t i = 0; i + 1 < logs.size(); ++i) {  // Killian's, last, from its import
    specs += " " + data + "/" + logs[i].first + ":" + data + "/" + logs[i].second;
  }
  specs += " " + dir.file("mit-killian.lcm") + ":" + dir.file("killian.relations");
  const auto r = test::run_capture(std::string(DRIFTLAB_SOURCE_DIR) + "/scripts/slam-robustness --jobs 2 --bin " +
                                   DRIFTLAB_BIN_DIR + " --json " + dir.file("runs.json") + specs);
  ASSERT_EQ(r.code, 0) << r.err;
  std::printf("%s", r.out.c_str());
  std::ifstream in(dir.file("runs.json"));
  const auto runs = nlohmann::json::parse(in)["runs"];
  const std::vector<std::pair<std::string, std::string>> rows = {{"fr079", "Freiburg 079"},
                                                                 {"mit-csail", "MIT CSAIL"},
                                                                 {"fr-clinic_robotlaser", "Freiburg clinic"},
                                                                 {"mit-killian", "MIT Killian Court"}};
  for (const auto& [log, label] : rows) {
    double meets = 0, total = 0;
    std::vector<double> failing;  // per failing run: its label's figure, its mean, its largest error
    for (const auto& run : runs) {
      if (run["log"] != log) continue;
      ++total;
      if (run["meets_bar"].get<bool>()) {
        ++meets;
        continue;
      }
      for (const auto& figure : test::printed_numbers(run["label"].get<std::string>())) {
        failing.push_back(std::stod(figure));
      }
      failing.push_back(run["mean_m"].get<double>());
      failing.push_back(run["max_m"].get<double>());
    }
    EXPECT_EQ(total, 10) << log;
    test::expect_doc_figures("docs/slam.md", "### How robust: ten runs of each log", label, 1, {meets, total});
    test::expect_doc_figures("docs/slam.md", "### How robust: ten runs of each log", label, 2, failing);
  }
}

}  // namespace
}  // namespace driftlab
