// batch/demo.h: `driftlab demo`'s two stories as data, called in-process: the stages each story runs and the report
// after them, and the summary read back from stage files written by the libraries that write them (a real
// diagnosis of the sample log, real evaluations, a replay's module reports), without running a stage.
#include "batch/demo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "analyzers/evaluate.h"
#include "runtime/module_report.h"
#include "tests/test_util.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

bool has(const std::vector<std::string>& args, const std::vector<std::string>& run) {
  return std::search(args.begin(), args.end(), run.begin(), run.end()) != args.end();
}

TEST(DemoPlan, TheGroundStoryReplaysAsLoggedAndCorrectedAndScoresBoth) {
  test::TempDir dir;
  DemoSettings s;
  s.out = dir.path();
  s.duration = 20;
  s.seed = 7;
  s.estimator_window = 0.5;
  auto p = plan_demo(s, "/x/driftlab");
  ASSERT_TRUE(p) << p.error().message;
  std::vector<std::string> verbs;
  for (const auto& st : p->stages) verbs.push_back(st.args.at(1));
  EXPECT_EQ(verbs, (std::vector<std::string>{"sim", "diagnose", "replay", "replay", "eval", "eval"}));
  EXPECT_EQ(p->stages[0].args[0], "/x/driftlab");
  EXPECT_TRUE(has(p->stages[0].args, {"--duration", "20", "-o", dir.file("sim.lcm")}));
  EXPECT_TRUE(has(p->stages[0].args, {"--seed", "7"}));
  // The second replay is the first with the clocks the diagnosis finds corrected; both read the settings written.
  EXPECT_FALSE(has(p->stages[2].args, {"--restamp", "auto"}));
  EXPECT_TRUE(has(p->stages[3].args, {"--restamp", "auto", "-o", dir.file("restamped.lcm")}));
  EXPECT_TRUE(has(p->stages[3].args, {"--config", dir.file("replay.yaml")}));
  std::ifstream config(dir.file("replay.yaml"));
  const std::string text((std::istreambuf_iterator<char>(config)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("estimator:\n  window_s: 0.5\n"), std::string::npos) << text;
  EXPECT_TRUE(has(p->stages[5].args, {"--est", dir.file("restamped.lcm") + ":EKF_ODOM", "--align", "posyaw"}));
  EXPECT_EQ(p->stages[5].stdout_file, dir.file("eval-after.txt"));
  EXPECT_EQ(p->report_logs,
            (std::vector<std::string>{dir.file("sim.lcm"), dir.file("replay.lcm"), dir.file("restamped.lcm")}));
  EXPECT_EQ(p->report_dir, dir.file("report"));
  EXPECT_EQ(p->title, "driftlab demo: 20 s of the default scenario");
  EXPECT_EQ(command_text(p->report_command),
            "driftlab report " + dir.file("sim.lcm") + " " + dir.file("replay.lcm") + " " + dir.file("restamped.lcm") +
                " --diagnosis " + dir.file("diagnosis.json") + " --eval " + dir.file("eval-before.json") + " --eval " +
                dir.file("eval-after.json") + " -o " + dir.file("report"));

  // A folder the settings cannot be written to: one line naming the file.
  s.out = dir.file("absent");
  auto bad = plan_demo(s, "driftlab");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, dir.file("absent/replay.yaml") + ": cannot write: No such file or directory");
  EXPECT_EQ(bad.error().code, ErrorCode::kCannotWrite);
}

TEST(DemoPlan, TheDroneStoryFliesAgainInClosedLoopAndScoresThreeFlights) {
  test::TempDir dir;
  DemoSettings s;
  s.out = dir.path();
  s.drone = true;
  auto p = plan_demo(s, "driftlab");
  ASSERT_TRUE(p) << p.error().message;
  ASSERT_EQ(p->stages.size(), 10u);  // two flights simulated, a diagnosis, one flown again, three flights scored twice
  EXPECT_NE(p->stages[1].args[2].find("drone_timebase.yaml"), std::string::npos);
  EXPECT_FALSE(has(p->stages[1].args, {"--seed"}));  // -1: the scenario's own
  EXPECT_TRUE(has(p->stages[3].args, {"--closed-loop", "--restamp", "auto"}));
  int scored = 0;
  for (const char* flight : {"clean.lcm", "sim.lcm", "restamped.lcm"}) {
    for (const auto& st : p->stages) scored += has(st.args, {"--gt", dir.file(flight) + ":GROUND_TRUTH"}) ? 1 : 0;
  }
  EXPECT_EQ(scored, 6);
  EXPECT_EQ(p->evals,
            (std::vector<std::string>{dir.file("estimate-logged.json"), dir.file("estimate-restamped.json")}));
  EXPECT_EQ(p->title, "driftlab demo --drone: drone_timebase, as flown and flown again");
}

TEST(RunStages, StopsAtTheFirstFailureSayingItsLastLineAndDroppingItsOutput) {
  test::TempDir dir;
  DemoPlan p;
  p.stages = {{"first", {"/bin/sh", "-c", "echo made; echo working >&2"}, dir.file("first.txt")},
              {"second", {"/bin/sh", "-c", "echo half; echo 'x.lcm: not a log' >&2; exit 2"}, dir.file("second.txt")},
              {"third", {"/bin/sh", "-c", "echo never"}, dir.file("third.txt")}};
  std::vector<size_t> around;
  const auto runs = run_stages(p, dir.path(), [&](size_t i, const std::function<void()>& run) {
    around.push_back(i);
    run();
  });
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(around, (std::vector<size_t>{0, 1}));
  EXPECT_EQ(runs[0].name, "-c");  // a stage is named by its subcommand, args[1]
  EXPECT_EQ(runs[0].code, 0);
  EXPECT_EQ(runs[1].code, 2);
  EXPECT_EQ(runs[1].said, "x.lcm: not a log");
  // The finished stage's output is kept; the failed one's (cut short) is not, nor the errors file; the third never ran.
  EXPECT_EQ(test::read_file(dir.file("first.txt")), (std::vector<uint8_t>{'m', 'a', 'd', 'e', '\n'}));
  EXPECT_FALSE(fs::exists(dir.file("second.txt")));
  EXPECT_FALSE(fs::exists(dir.file("stage.err")));
  EXPECT_FALSE(fs::exists(dir.file("third.txt")));
  const nlohmann::json j = to_json(runs);
  EXPECT_EQ(j.size(), 2u);
  EXPECT_GE(j[1]["seconds"].get<double>(), 0.0);
}

/// An evaluation `eval --json-out` would write: a straight line estimated `offset` metres to its side.
void write_eval(const std::string& path, const test::TempDir& dir, double offset) {
  std::ofstream gt(dir.file("gt.tum")), est(dir.file("est.tum"));
  for (int i = 0; i < 50; ++i) {
    gt << 10 + 0.1 * i << " " << 0.1 * i << " 0 0 0 0 0 1\n";
    est << 10 + 0.1 * i << " " << 0.1 * i << " " << offset << " 0 0 0 0 1\n";
  }
  gt.close();
  est.close();
  analyzers::EvaluateOptions o;
  o.gt = dir.file("gt.tum");
  o.est = dir.file("est.tum");
  auto ev = analyzers::evaluate(o);
  ASSERT_TRUE(ev) << ev.error().message;
  std::ofstream(path) << to_json(*ev).dump();
}

TEST(DemoSummary, TheGroundStorysLinesFromItsStagesFiles) {
  test::TempDir dir;
  DemoSettings s;
  s.out = dir.path();
  auto p = plan_demo(s, "driftlab");
  ASSERT_TRUE(p);
  auto run = analyzers::run_diagnosis(std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm", {});
  ASSERT_TRUE(run) << run.error().message;
  std::ofstream(p->diagnosis) << to_json(run->diagnosis).dump();
  write_eval(p->evals[0], dir, 0.2);
  write_eval(p->evals[1], dir, 0.05);
  for (auto [name, late] : {std::pair{"replay.json", 40.0}, std::pair{"restamped.json", 3.0}}) {
    runtime::ModuleReport estimator{.name = "estimator", .metrics = {{"late_rejected", late}}};
    std::ofstream(dir.file(name)) << nlohmann::json{{"modules", runtime::to_json({estimator})}}.dump();
  }
  auto summary = read_demo(s, *p);
  ASSERT_TRUE(summary) << summary.error().message;
  EXPECT_NEAR(summary->ate_before, 0.2, 1e-9);
  EXPECT_NEAR(summary->ate_after, 0.05, 1e-9);
  EXPECT_EQ(summary->late_rejected_before, 40);
  EXPECT_EQ(summary->late_rejected_after, 3);
  // The sample log's one fault is SCAN's clock (tests/analyzers/diagnosis_text_test.cc).
  const std::string text = demo_text(s, *summary);
  EXPECT_EQ(text.rfind("\nworst stream:  SCAN (fault): ", 0), 0u) << text;
  EXPECT_NE(
      text.find("\ndrops:         none\n"
                "ATE:           EKF_ODOM 0.200 m as logged, 0.050 m with corrected clocks (-75%; late measurements "
                "dropped: 40, then 3)\n"),
      std::string::npos)
      << text;
  const nlohmann::json j = to_json(s, *summary);
  EXPECT_EQ(j["worst_stream"]["name"], "SCAN");
  EXPECT_EQ(j["late_rejected_before"], 40);
  EXPECT_EQ(j["estimate"], "EKF_ODOM");
  EXPECT_TRUE(j.contains("drops"));
  EXPECT_FALSE(j.contains("tracking_m"));

  // A stage's file that is not what the stage writes: one line naming it.
  std::ofstream(p->evals[1]) << "{\"ate\": 3}";
  auto bad = read_demo(s, *p);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message.rfind(p->evals[1] + ": ", 0), 0u) << bad.error().message;
  EXPECT_EQ(bad.error().message.find('\n'), std::string::npos);
  fs::remove(dir.file("restamped.json"));
  write_eval(p->evals[1], dir, 0.05);
  bad = read_demo(s, *p);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, dir.file("restamped.json") + ": not JSON");
}

}  // namespace
}  // namespace driftlab::batch
