// batch/plan.h and batch/store.h: specs read and checked (bad ones named by file and key), grids expanded, point
// ids stable, the inputs a point writes (faults, module settings), atomic files and the merged table.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>

#include "batch/plan.h"
#include "batch/spec.h"
#include "batch/store.h"
#include "core/text_file.h"
#include "faults/faults.h"
#include "modules/module_table.h"
#include "tests/test_util.h"

namespace driftlab::batch {
namespace {

const std::string kScenario = std::string(DRIFTLAB_SOURCE_DIR) + "/sim/scenarios/indoor.yaml";

std::string write_spec(const test::TempDir& dir, const std::string& body, const std::string& name = "spec.yaml") {
  const std::string path = dir.file(name);
  std::ofstream(path) << "scenario: " << kScenario << "\n" << body;
  return path;
}

std::string spec_error(const std::string& body) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir, body));
  if (s) return "(accepted)";
  // Every message names the spec file.
  EXPECT_EQ(s.error().message.rfind(dir.file("spec.yaml"), 0), 0u) << s.error().message;
  EXPECT_EQ(s.error().message.find('\n'), std::string::npos);
  return s.error().message;
}

TEST(SweepSpec, GridsListsAndStableIds) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir,
                                "duration: 5\nmodules: estimator\n"
                                "vary:\n  faults.IMU.clock_offset_s: {from: 0, to: 0.2, step: 0.05}\n"
                                "  seed: [1, 2, 3]\n"));
  ASSERT_TRUE(s) << s.error().message;
  ASSERT_EQ(s->vary.size(), 2u);
  std::vector<std::string> texts;
  for (const auto& v : s->vary[0].values) texts.push_back(v.text);
  EXPECT_EQ(texts, (std::vector<std::string>{"0", "0.05", "0.1", "0.15", "0.2"}));  // no 0.15000000000000002
  const auto points = expand(*s);
  ASSERT_EQ(points.size(), 15u);
  std::set<std::string> ids;
  for (const auto& p : points) ids.insert(p.id);
  EXPECT_EQ(ids.size(), 15u);
  EXPECT_EQ(points[0].id.size(), 12u);
  // The default pipeline for a scenario with modules.
  EXPECT_EQ(s->stages, (std::vector<Stage>{Stage::kSim, Stage::kReplay, Stage::kDiagnose, Stage::kEval}));

  // The same spec read again gives the same ids; a grid that grows keeps the ids of the points it had, and the
  // spec's name is not part of what a point computes.
  auto again = load_spec(write_spec(dir,
                                    "name: other\nduration: 5\nmodules: estimator\n"
                                    "vary:\n  faults.IMU.clock_offset_s: [0, 0.05, 0.1, 0.15, 0.2, 0.25]\n"
                                    "  seed: [1, 2, 3]\n",
                                    "again.yaml"));
  ASSERT_TRUE(again) << again.error().message;
  std::set<std::string> ids2;
  for (const auto& p : expand(*again)) ids2.insert(p.id);
  for (const auto& id : ids) EXPECT_TRUE(ids2.count(id)) << id;
  EXPECT_EQ(ids2.size(), 18u);

  // What the point computes changes its id: another duration is another point.
  auto longer = load_spec(write_spec(dir, "duration: 6\nmodules: estimator\nvary:\n  seed: [1]\n", "longer.yaml"));
  auto shorter = load_spec(write_spec(dir, "duration: 5\nmodules: estimator\nvary:\n  seed: [1]\n", "shorter.yaml"));
  ASSERT_TRUE(longer && shorter);
  EXPECT_NE(expand(*longer)[0].id, expand(*shorter)[0].id);
}

TEST(SweepSpec, BadSpecsNameTheFileAndTheKey) {
  // An unknown parameter.
  EXPECT_NE(spec_error("vary:\n  speed: [1, 2]\n").find("vary: speed: unknown parameter"), std::string::npos);
  // An unknown fault field, caught by the fault model's own parser.
  const std::string field = spec_error("vary:\n  faults.IMU.clock_ofset_s: [0, 0.1]\n");
  EXPECT_NE(field.find("vary: faults.IMU.clock_ofset_s: unknown key 'clock_ofset_s'"), std::string::npos) << field;
  // A channel the scenario does not publish.
  EXPECT_NE(spec_error("vary:\n  faults.GPS.latency_s: [0, 0.1]\n").find("publishes no channel GPS"), std::string::npos);
  // Empty grids and lists.
  EXPECT_NE(spec_error("vary:\n  seed: []\n").find("vary: seed: empty list"), std::string::npos);
  EXPECT_NE(spec_error("vary:\n  faults.IMU.latency_s: {from: 0.2, to: 0, step: 0.1}\n").find("empty grid"),
            std::string::npos);
  EXPECT_NE(spec_error("vary:\n  faults.IMU.latency_s: {from: 0, to: 1, count: 0}\n").find("empty grid"),
            std::string::npos);
  // Values of the wrong type or out of range.
  EXPECT_NE(spec_error("vary:\n  faults.IMU.clock_offset_s: [0, fast]\n").find("vary: faults.IMU.clock_offset_s: fault values must be numbers"),
            std::string::npos);
  EXPECT_NE(spec_error("vary:\n  faults.SCAN.drop_probability: [0.1, 1.5]\n").find("outside 0..1"), std::string::npos);
  EXPECT_NE(spec_error("vary:\n  seed: [1, -2]\n").find("vary: seed: -2 is not a non-negative whole number"),
            std::string::npos);
  EXPECT_NE(spec_error("vary:\n  seed: [1, 2.5]\n").find("vary: seed: 2.5"), std::string::npos);
  EXPECT_NE(spec_error("modules: estimator\nvary:\n  restamp: [none, maybe]\n").find("vary: restamp: maybe"),
            std::string::npos);
  EXPECT_NE(spec_error("vary:\n  seed: 3\n").find("vary: seed: expected a list"), std::string::npos);
  EXPECT_NE(spec_error("vary:\n  seed: [1, 1]\n").find("given twice"), std::string::npos);
  // Module settings need a replay; unknown top-level keys and modules.
  EXPECT_NE(spec_error("vary:\n  estimator.window_s: [0, 0.5]\n").find("need a replay stage"), std::string::npos);
  EXPECT_NE(spec_error("modules: [estimator, planner]\n").find("modules: unknown module 'planner'"), std::string::npos);
  EXPECT_NE(spec_error("grid:\n  seed: [1]\n").find(":2: unknown key 'grid' (known: scenario, logs, name,"),
            std::string::npos);
  EXPECT_NE(spec_error("duration: -1\n").find(":2: duration = -1 must be > 0"), std::string::npos);
  EXPECT_NE(spec_error("seed: 2.5\n").find(":2: seed "), std::string::npos);
  EXPECT_NE(spec_error("eval: {align: wobbly}\n").find(":2: eval.align = wobbly must be none, se3, sim3 or posyaw"),
            std::string::npos);
  EXPECT_NE(spec_error("keep_logs: maybe\n").find(":2: keep_logs = maybe must be true or false"), std::string::npos);
  EXPECT_NE(spec_error("pipeline: [sim, fly]\n").find(":2: pipeline: unknown stage 'fly'"), std::string::npos);
  EXPECT_NE(spec_error("faults:\n  streams:\n    IMU: {clock_offset_s: x}\n").find("must be a number"),
            std::string::npos);
  // Bad YAML.
  EXPECT_NE(spec_error("vary: [\n").find(":"), std::string::npos);
}

// Two grids of 10,000 values each were each accepted, and their product (10^8 points) exhausted memory when the
// sweep expanded it (issue 31). The product is bounded, said with its factors; at the bound it is accepted.
// A sweep offers every module replay hosts, from the one table (modules/module_table.h): the drone's modules and
// their settings too (a copy of the names here once drifted to three of six), and an unknown module's message lists
// them all.
TEST(SweepSpec, EveryModuleOfTheTableIsAModuleOfASweep) {
  test::TempDir dir;
  std::string all;
  for (const auto& k : modules::kModuleKinds) (all += all.empty() ? "" : ", ") += k.name;
  auto s = load_spec(write_spec(dir, "modules: [" + all + "]\nvary:\n  flight.position_rate: [50, 100]\n"));
  ASSERT_TRUE(s) << s.error().message;
  std::string joined(all);
  joined.erase(std::remove(joined.begin(), joined.end(), ' '), joined.end());
  EXPECT_EQ(s->modules, joined);
  const std::string e = spec_error("modules: [estimator, planner]\n");
  EXPECT_NE(e.find("unknown module 'planner' (" + all + ")"), std::string::npos) << e;
  EXPECT_NE(spec_error("settings:\n  planner: {x: 1}\n").find("unknown module (" + all + ")"), std::string::npos);
}

TEST(SweepSpec, AProductOfGridsBeyondTheBoundIsRefusedWithItsFactors) {
  const std::string e = spec_error(
      "vary:\n  faults.IMU.latency_s: {from: 0, to: 1, count: 10000}\n  seed: {from: 0, to: 9999, step: 1}\n");
  EXPECT_NE(e.find("vary: 10000 x 10000 = 100000000 points, more than the 100000 a sweep may have"), std::string::npos)
      << e;
  EXPECT_EQ(spec_error("vary:\n  faults.IMU.latency_s: {from: 0, to: 1, count: 10}\n  seed: {from: 0, to: 9999, "
                       "step: 1}\n"),
            "(accepted)");
}

TEST(SweepSpec, PointInputs) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir,
                                "modules: estimator\nsettings:\n  estimator: {window_s: 0}\n"
                                "vary:\n  faults.IMU.clock_offset_s: [0.05]\n  estimator.publish_rate: [25]\n"
                                "  restamp: [auto]\n"));
  ASSERT_TRUE(s) << s.error().message;
  const auto points = expand(*s);
  ASSERT_EQ(points.size(), 1u);
  // Faults: the scenario's own (docs/simulator.md: SCAN drops, ODOM jitter, IMU offset) with the varied field set.
  const std::string faults = faults_yaml(*s, points[0]);
  auto parsed = parse_faults(faults, "faults");
  ASSERT_TRUE(parsed) << parsed.error().message << "\n" << faults;
  EXPECT_DOUBLE_EQ(parsed->streams.at("IMU").clock_offset_s, 0.05);
  EXPECT_TRUE(parsed->streams.count("SCAN")) << faults;
  const std::string config = module_config_yaml(*s, points[0]);
  EXPECT_NE(config.find("estimator:"), std::string::npos) << config;
  EXPECT_NE(config.find("window_s: 0"), std::string::npos) << config;
  EXPECT_NE(config.find("publish_rate: 25"), std::string::npos) << config;
  EXPECT_EQ(restamp_of(*s, points[0]), "auto");
  // Nothing varied or given: the scenario's faults stay the simulator's business.
  auto plain = load_spec(write_spec(dir, "vary:\n  seed: [1]\n", "plain.yaml"));
  ASSERT_TRUE(plain);
  EXPECT_EQ(faults_yaml(*plain, expand(*plain)[0]), "");
  EXPECT_EQ(module_config_yaml(*plain, expand(*plain)[0]), "");
}

/// A sweep's module settings are checked, in-process, against the modules' own tables before any point runs:
/// every varied value and the spec's fixed settings; the error names the spec's key and says what the table says.
TEST(SweepSpec, ModuleSettingsCheckedAgainstTheModulesTables) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir, "modules: estimator\nvary:\n  estimator.window_s: [0, 0.5, oops]\n"));
  ASSERT_TRUE(s) << s.error().message;
  Status st = validate_module_settings(*s);
  ASSERT_FALSE(st);
  EXPECT_EQ(st.message().rfind(
                dir.file("spec.yaml") + ": vary: estimator.window_s = oops: the modules refuse it: settings:", 0),
            0u)
      << st.message();
  EXPECT_NE(st.message().find("estimator.window_s"), std::string::npos) << st.message();

  auto good = load_spec(write_spec(dir, "modules: estimator\nvary:\n  estimator.window_s: [0, 0.5]\n", "good.yaml"));
  ASSERT_TRUE(good) << good.error().message;
  EXPECT_TRUE(validate_module_settings(*good));
  // A fixed setting out of its range, and a key the module does not have.
  auto range = load_spec(write_spec(
      dir, "modules: estimator\nsettings:\n  estimator: {window_s: -1}\nvary:\n  seed: [1]\n", "range.yaml"));
  ASSERT_TRUE(range) << range.error().message;
  st = validate_module_settings(*range);
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find(": settings: the modules refuse it: settings:"), std::string::npos) << st.message();
  auto typo =
      load_spec(write_spec(dir, "modules: slam\nsettings:\n  slam: {backnd: 2d}\nvary:\n  seed: [1]\n", "typo.yaml"));
  ASSERT_TRUE(typo) << typo.error().message;
  st = validate_module_settings(*typo);
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find("backnd"), std::string::npos) << st.message();
  // Of two varied keys with the same name in two sections, the one refused is named, checked on its own (the
  // message names the key as the module's table does, which need not be how the spec spells it).
  auto twin = load_spec(
      write_spec(dir, "modules: slam\nvary:\n  slam.2d.keyframe_distance: [0.5]\n  slam.3d.keyframe_distance: [-1]\n",
                 "twin.yaml"));
  ASSERT_TRUE(twin) << twin.error().message;
  st = validate_module_settings(*twin);
  ASSERT_FALSE(st);
  EXPECT_NE(st.message().find(": vary: slam.3d.keyframe_distance = -1: the modules refuse it:"), std::string::npos)
      << st.message();
}

/// A module's sections (slam's 2d and 3d): a varied `slam.2d.KEY` and the spec's nested settings go into one map
/// of the section, which the module's table reads as `driftlab replay --config` does.
TEST(SweepSpec, SectionSettingsNestInTheConfigFile) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir,
                                "modules: slam\nsettings:\n  slam: {backend: 2d, 2d: {keyframe_distance: 0.6}}\n"
                                "vary:\n  slam.2d.loop_radius: [1, 2]\n  slam.3d.keyframe_distance: [0.5]\n"));
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_TRUE(validate_module_settings(*s));
  const std::string config = module_config_yaml(*s, expand(*s)[1]);
  const YAML::Node root = YAML::Load(config);
  EXPECT_EQ(root["slam"]["backend"].as<std::string>(), "2d") << config;
  EXPECT_EQ(root["slam"]["2d"]["keyframe_distance"].as<double>(), 0.6) << config;
  EXPECT_EQ(root["slam"]["2d"]["loop_radius"].as<double>(), 2) << config;
  EXPECT_EQ(root["slam"]["3d"]["keyframe_distance"].as<double>(), 0.5) << config;
  // A list where a value belongs, at any depth, is refused where it stands.
  auto deep = load_spec(
      write_spec(dir, "modules: slam\nsettings:\n  slam: {2d: {loop_radius: [1]}}\nvary:\n  seed: [1]\n", "deep.yaml"));
  ASSERT_FALSE(deep);
  EXPECT_NE(deep.error().message.find("settings: slam.2d.loop_radius: expected a single value"), std::string::npos)
      << deep.error().message;
}

TEST(SweepSpec, PlanRoundTripsThroughJson) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir, "modules: estimator\nvary:\n  seed: [1, 2]\n  restamp: [none, auto]\n"));
  ASSERT_TRUE(s);
  const Plan plan{*s, expand(*s)};
  ASSERT_TRUE(save_plan(dir.file("sweep"), plan));
  auto back = load_plan(dir.file("sweep"));
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(to_json(*back).dump(), to_json(plan).dump());
  // Expanding the stored spec gives the stored ids (a task on another node finds its point).
  const auto again = expand(back->spec);
  ASSERT_EQ(again.size(), plan.points.size());
  for (size_t i = 0; i < again.size(); ++i) EXPECT_EQ(again[i].id, plan.points[i].id);
  EXPECT_FALSE(load_plan(dir.file("nowhere")));
}

TEST(SweepStore, AtomicFilesAndTheMergedTable) {
  test::TempDir dir;
  auto s = load_spec(write_spec(dir, "modules: estimator\nvary:\n  seed: [1, 2, 3]\n"));
  ASSERT_TRUE(s);
  const Plan plan{*s, expand(*s)};
  ASSERT_TRUE(save_plan(dir.file("d"), plan));
  const std::string d = dir.file("d");
  std::filesystem::create_directories(point_dir(d, plan.points[0].id));
  std::filesystem::create_directories(point_dir(d, plan.points[1].id));
  ASSERT_TRUE(write_file_atomically(
      result_path(d, plan.points[0].id),
      R"({"metrics": {"ate_rmse": 0.25, "worst_stream": "IMU, late"}, "seconds": {"sim": 1.5}})"));
  EXPECT_FALSE(std::filesystem::exists(result_path(d, plan.points[0].id) + ".partial"));
  ASSERT_TRUE(
      write_file_atomically(point_dir(d, plan.points[1].id) + "/failed.json", R"({"error": "sim exited with 1"})"));
  EXPECT_EQ(count_attempt(d, plan.points[1].id), 1);
  EXPECT_EQ(count_attempt(d, plan.points[1].id), 2);
  EXPECT_EQ(point_status(d, plan.points[0].id).state, PointState::kDone);
  EXPECT_EQ(point_status(d, plan.points[1].id).state, PointState::kFailed);
  EXPECT_EQ(point_status(d, plan.points[1].id).attempts, 2);
  EXPECT_EQ(point_status(d, plan.points[2].id).state, PointState::kPending);
  // A running marker of this host whose process is gone: killed outright, so failed (and run again).
  const pid_t gone = fork();
  if (gone == 0) _exit(0);
  waitpid(gone, nullptr, 0);
  std::filesystem::create_directories(point_dir(d, "stale"));
  ASSERT_TRUE(write_file_atomically(point_dir(d, "stale") + "/running.json",
                                    nlohmann::json{{"host", host_name()}, {"pid", gone}}.dump()));
  EXPECT_EQ(point_status(d, "stale").state, PointState::kFailed);
  ASSERT_TRUE(write_file_atomically(point_dir(d, "stale") + "/running.json",
                                    nlohmann::json{{"host", host_name()}, {"pid", getpid()}}.dump()));
  EXPECT_EQ(point_status(d, "stale").state, PointState::kRunning);

  const Table t = merge_results(d, plan);
  EXPECT_EQ(t.columns, (std::vector<std::string>{"id", "status", "attempts", "seed", "ate_rmse", "error",
                                                 "worst_stream", "seconds.sim"}));
  const std::string csv = table_csv(t);
  EXPECT_NE(csv.find(plan.points[0].id + ",done,0,1,0.25,,\"IMU, late\",1.5\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find(plan.points[1].id + ",failed,2,2,,sim exited with 1,,\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find(plan.points[2].id + ",pending,0,3,,,,\n"), std::string::npos) << csv;
}

}  // namespace
}  // namespace driftlab::batch
