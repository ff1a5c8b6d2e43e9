// batch/session.h: what `driftlab sweep` and `driftlab batch` do with a sweep's folder, called in-process: a
// batch's logs expanded, the folder refused when it would overwrite an input, the pending points run on the local
// pool (each point here a stand-in for `driftlab batch --item`, so the test is about the session, not the stages),
// resumed, counted and merged.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "batch/session.h"
#include "batch/spec.h"
#include "tests/test_util.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

TEST(BatchLogs, ListsPatternsAndPathsAreExpandedAndAMissNamed) {
  test::TempDir dir;
  fs::create_directories(dir.file("week"));
  for (const char* name : {"week/a.lcm", "week/b.lcm", "week/notes.txt", "c.lcm"}) std::ofstream(dir.file(name)) << "x";
  std::ofstream(dir.file("week/list.txt")) << "# the week's logs\n  a.lcm \n\n" << dir.file("c.lcm") << "\n";
  auto logs = batch_logs({"@" + dir.file("week/list.txt"), dir.file("week/*.lcm"), "plain.lcm"}, "");
  ASSERT_TRUE(logs) << logs.error().message;
  // The list's relative entries are relative to the list; a pattern is expanded in order; a plain path is kept
  // as given (its absence is the stage's to report).
  EXPECT_EQ(*logs, (std::vector<std::string>{dir.file("week/a.lcm"), dir.file("c.lcm"), dir.file("week/a.lcm"),
                                             dir.file("week/b.lcm"), "plain.lcm"}));
  auto listed = batch_logs({}, dir.file("week/list.txt"));
  ASSERT_TRUE(listed);
  EXPECT_EQ(listed->size(), 2u);

  auto miss = batch_logs({dir.file("week/*.bag")}, "");
  ASSERT_FALSE(miss);
  EXPECT_EQ(miss.error().message, dir.file("week/*.bag") + ": matches no file");
  std::ofstream(dir.file("bad.txt")) << "nothing-*.lcm\n";
  auto bad_list = batch_logs({"@" + dir.file("bad.txt")}, "");
  ASSERT_FALSE(bad_list);
  EXPECT_EQ(bad_list.error().message, dir.file("bad.txt") + ": " + dir.file("nothing-*.lcm") + ": matches no file");
  EXPECT_FALSE(batch_logs({}, dir.file("absent.txt")));
}

TEST(CheckSweepDir, AFolderThatIsOrHoldsAnInputIsRefused) {
  test::TempDir dir;
  const std::string log = dir.file("run/points/x/in.lcm");
  fs::create_directories(fs::path(log).parent_path());
  std::ofstream(log) << "x";
  std::ofstream(dir.file("file")) << "x";
  EXPECT_TRUE(check_sweep_dir(dir.file("new"), {log}));
  auto is_file = check_sweep_dir(dir.file("file"), {});
  ASSERT_FALSE(is_file);
  EXPECT_NE(is_file.message().find("is a regular file, not a folder"), std::string::npos) << is_file.message();
  // The points' folders are cleared and rewritten: an input there would be lost.
  auto inside = check_sweep_dir(dir.file("run"), {log});
  ASSERT_FALSE(inside);
  EXPECT_NE(inside.message().find("lies in " + dir.file("run/points")), std::string::npos) << inside.message();
  // results.csv is written at the top: an input of that name would be overwritten.
  std::ofstream(dir.file("run/results.csv")) << "x";
  EXPECT_FALSE(check_sweep_dir(dir.file("run"), {dir.file("run/results.csv")}));
}

/// A stand-in for `driftlab batch --item ID -o DIR`: the point of the log named bad.lcm fails as the runner
/// records a failure (failed.json, exit 1); the others finish (result.json, the done-marker).
std::string write_stand_in(const test::TempDir& dir, const std::string& bad_id) {
  std::string path = dir.file("driftlab");
  std::ofstream(path) << "#!/bin/sh\n"
                         "# $1 $2: batch --item; $3: ID; $5: DIR\n"
                         "p=\"$5/points/$3\"; mkdir -p \"$p\"\n"
                         "if [ \"$3\" = \""
                      << bad_id
                      << "\" ]; then echo '{\"error\": \"diagnose: bad.lcm: not a log\"}' > \"$p/failed.json\"; "
                         "exit 1; fi\n"
                         "echo \"{\\\"id\\\": \\\"$3\\\", \\\"status\\\": \\\"done\\\"}\" > \"$p/result.json\"\n";
  ::chmod(path.c_str(), 0755);
  return path;
}

TEST(RunLocally, PendingPointsRunFailuresAreCountedAndARunResumes) {
  test::TempDir dir;
  std::vector<std::string> logs;
  for (const char* name : {"a.lcm", "b.lcm", "bad.lcm"}) {
    logs.push_back(dir.file(name));
    std::ofstream(logs.back()) << "x";
  }
  auto spec = batch_spec("diagnose", logs);
  ASSERT_TRUE(spec) << spec.error().message;
  const Plan plan{*spec, expand(*spec)};
  ASSERT_EQ(plan.points.size(), 3u);
  std::string bad_id;
  for (const auto& p : plan.points) {
    if (p.get("log")->text == logs[2]) bad_id = p.id;
  }
  ASSERT_FALSE(bad_id.empty());
  const std::string out = dir.file("out");
  RunOptions o;
  o.driftlab = write_stand_in(dir, bad_id);
  o.point_flag = "batch --item";
  o.jobs = 2;
  EXPECT_EQ(pending_points(out, plan).size(), 3u);

  auto run = run_locally(out, plan, o);
  ASSERT_TRUE(run) << run.error().message;
  EXPECT_EQ(run->summary.done, 2u);
  EXPECT_EQ(run->summary.failed, 1u);
  EXPECT_EQ(run->already_done, 0u);
  EXPECT_EQ(run->jobs, 2);
  EXPECT_TRUE(fs::exists(plan_path(out)));  // saved before anything ran, so status and collect can read it
  // What the command prints of the run: with the page drawn, without it, and when collecting failed.
  const std::string ran = local_run_text(*run, out, out + "/index.html");
  EXPECT_EQ(ran.substr(ran.find(':')),
            ": 2 done, 1 failed\ntable: " + out + "/results.csv, page: " + out + "/index.html\n");
  EXPECT_EQ(ran.rfind("ran 3 points in ", 0), 0u) << ran;
  EXPECT_EQ(local_run_text(*run, out, "").substr(ran.find(':')),
            ": 2 done, 1 failed\ntable: " + out + "/results.csv\n");
  EXPECT_EQ(local_run_text(*run, out, std::nullopt).find("table:"), std::string::npos);
  const nlohmann::json summary = to_json(*run, out, plan, "");
  EXPECT_EQ(summary["points"], 3);
  EXPECT_EQ(summary["failed"], 1);
  EXPECT_FALSE(summary.contains("page"));

  const SweepState state = sweep_state(out, plan, false);
  EXPECT_EQ(state.count(PointState::kDone), 2u);
  EXPECT_EQ(state.count(PointState::kFailed), 1u);
  EXPECT_EQ(state_text(state, out), out + ": 3 points: 2 done, 0 running, 1 failed, 0 pending\n  failed " + bad_id +
                                        " (attempt 0): diagnose: bad.lcm: not a log\n");
  const nlohmann::json j = to_json(state, out);
  EXPECT_EQ(j["failed"], 1);
  EXPECT_EQ(j["failures"][0]["id"], bad_id);
  const std::string dry = dry_run_text(out, plan);
  EXPECT_EQ(std::count(dry.begin(), dry.end(), '\n'), 3);
  EXPECT_NE(dry.find(bad_id + " pending log=" + logs[2]), std::string::npos) << dry;

  // Run again: only the failed point runs; the finished ones are kept.
  auto again = run_locally(out, plan, o);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->already_done, 2u);
  EXPECT_EQ(again->summary.done + again->summary.failed, 1u);

  auto tables = write_tables(out, plan);
  ASSERT_TRUE(tables) << tables.error().message;
  std::ifstream f(*tables);
  const nlohmann::json t = nlohmann::json::parse(f);
  EXPECT_EQ(t["rows"].size(), 3u);
  EXPECT_EQ(t["ranked"].size(), 3u);  // a batch over logs is ranked worst first
  EXPECT_TRUE(fs::exists(out + "/results.csv"));
}

TEST(SubmitToSlurm, NothingIsSubmittedWhenEveryPointIsDone) {
  test::TempDir dir;
  std::ofstream(dir.file("a.lcm")) << "x";
  auto spec = batch_spec("diagnose", {dir.file("a.lcm")});
  ASSERT_TRUE(spec);
  const Plan plan{*spec, expand(*spec)};
  const std::string out = dir.file("out");
  fs::create_directories(point_dir(out, plan.points[0].id));
  std::ofstream(result_path(out, plan.points[0].id)) << "{}";
  RunOptions o;
  o.sbatch = dir.file("no-sbatch-here");  // would fail if it were called
  auto r = submit_to_slurm(out, plan, o);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->job_id.empty());
  EXPECT_EQ(r->already_done, 1u);
  EXPECT_EQ(r->submitted, 0u);
  EXPECT_EQ(submission_text(*r, out, plan), "all 1 points of " + out + " are done; nothing submitted\n");
  EXPECT_EQ(
      submission_text({.job_id = "42", .submitted = 3, .already_done = 1}, out, plan),
      "submitted job 42: 3 points as a job array (1 already done); follow with: driftlab sweep status " + out + "\n");
}

}  // namespace
}  // namespace driftlab::batch
