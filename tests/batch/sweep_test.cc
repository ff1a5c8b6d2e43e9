// `driftlab sweep` and `driftlab batch` end to end on the local executor: a tiny sweep of short simulations through
// the estimator, diagnosis and eval (offsets found where they were injected), resumed without re-running finished
// points, stopped by Ctrl-C keeping what finished, deterministic across runs; bad specs refused before anything
// runs; a batch of logs diagnosed and ranked.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>

#include "tests/batch/sweep_util.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;

TEST(SweepCli, LocalSweepRunsResumesAndIsDeterministic) {
  test::TempDir dir;
  const std::string spec = test::write_tiny_spec(dir);
  const std::string out = dir.file("sweep");
  auto r = test::driftlab("sweep " + spec + " -o " + out + " -j 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["points"], 4);
  EXPECT_EQ(j["done"], 4);
  EXPECT_EQ(j["failed"], 0);
  EXPECT_TRUE(fs::exists(out + "/results.csv"));
  EXPECT_TRUE(fs::exists(out + "/index.html"));

  const auto rows = test::result_rows(out);
  ASSERT_EQ(rows.size(), 4u);
  for (const auto& row : rows) {
    ASSERT_EQ(row["status"], "done") << row.dump();
    EXPECT_GT(row["ate_rmse"].get<double>(), 0) << row.dump();
    EXPECT_GT(row["rpe_rmse"].get<double>(), 0) << row.dump();
    EXPECT_TRUE(row["estimator.late_rejected"].is_number()) << row.dump();
  }
  // The real stages ran with each point's own faults: the IMU clock ahead makes the estimator, which drops late
  // measurements, reject more of them and drift further, seed by seed.
  for (int seed : {1, 2}) {
    nlohmann::json with, without;
    for (const auto& row : rows) {
      if (row["seed"] == seed) (row["faults.IMU.clock_offset_s"].get<double>() > 0 ? with : without) = row;
    }
    EXPECT_GT(with["estimator.late_rejected"].get<double>(), without["estimator.late_rejected"].get<double>());
    EXPECT_GT(with["ate_rmse"].get<double>(), without["ate_rmse"].get<double>());
  }
  // Running it again runs nothing: the done-markers stand, and their files are untouched.
  const std::string first_result = out + "/points/" + rows[0]["id"].get<std::string>() + "/result.json";
  const auto mtime = fs::last_write_time(first_result);
  r = test::driftlab("sweep " + spec + " -o " + out + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["already_done"], 4);
  EXPECT_EQ(j["done"], 0);
  EXPECT_EQ(fs::last_write_time(first_result), mtime);

  // Status and collect from the folder alone.
  r = test::driftlab("sweep status " + out + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["done"], 4);
  r = test::driftlab("sweep collect " + out + " --no-plots");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("4 of 4 points done"), std::string::npos) << r.out;

  // The same spec with one process at a time gives the same numbers (the pipeline is deterministic).
  r = test::driftlab("sweep " + spec + " -o " + dir.file("serial") + " -j 1 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::metrics_by_id(dir.file("serial")), test::metrics_by_id(out));
}

TEST(SweepCli, CtrlCKeepsFinishedPointsAndResumes) {
  test::TempDir dir;
  const std::string spec = test::write_tiny_spec(dir);
  const std::string out = dir.file("sweep");
  // One at a time, so that the interrupt falls between points already done and points not started.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setpgid(0, 0);  // a process group of its own, as a terminal's foreground job
    const std::string exe = test::kDriftlab;
    execl(exe.c_str(), exe.c_str(), "sweep", spec.c_str(), "-o", out.c_str(), "-j", "1", static_cast<char*>(nullptr));
    _exit(127);
  }
  setpgid(pid, pid);
  // Wait for the first point to finish, then Ctrl-C the whole group (what a terminal does).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  auto done_points = [&] {
    int n = 0;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(out + "/points", ec)) n += fs::exists(e.path() / "result.json");
    return n;
  };
  while (done_points() < 1 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GE(done_points(), 1);
  kill(-pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  const int kept = done_points();
  if (kept < 4) {
    EXPECT_EQ(WEXITSTATUS(status), 130);
  }
  EXPECT_GE(kept, 1);
  // No point is half-marked: each folder has a whole result.json or none.
  for (const auto& e : fs::directory_iterator(out + "/points")) {
    EXPECT_FALSE(fs::exists(e.path() / "result.json.partial")) << e.path();
    if (fs::exists(e.path() / "result.json")) {
      std::ifstream f(e.path() / "result.json");
      EXPECT_TRUE(nlohmann::json::accept(f)) << e.path();
    }
  }
  // Resuming runs the rest only.
  const auto r = test::driftlab("sweep " + spec + " -o " + out + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["already_done"].get<int>(), kept);
  EXPECT_EQ(j["done"].get<int>(), 4 - kept);
}

TEST(SweepCli, BadSpecIsOneLineExitTwoNothingRun) {
  test::TempDir dir;
  struct Case {
    std::string body, key;
  };
  const std::vector<Case> cases = {
      {"vary:\n  faults.IMU.clock_offset_ms: [0, 0.1]\n", "faults.IMU.clock_offset_ms"},
      {"vary:\n  seed: []\n", "seed"},
      {"vary:\n  faults.IMU.latency_s: [0, soon]\n", "faults.IMU.latency_s"},
      {"vary:\n  wheel_radius: [0.1]\n", "wheel_radius"},
      // A module key only the replay program knows is wrong: asked of it before anything runs.
      {"modules: estimator\nvary:\n  estimator.imu_nois: [0.1, 0.2]\n", "estimator.imu_nois"},
      {"modules: estimator\nvary:\n  estimator.window_s: [0.5, wide]\n", "estimator.window_s"},
  };
  for (const auto& c : cases) {
    std::ofstream(dir.file("bad.yaml")) << "duration: 2\n" << c.body;
    const std::string out = dir.file("never");
    for (const char* executor : {"local", "slurm"}) {
      const auto r = test::driftlab("sweep " + dir.file("bad.yaml") + " -o " + out + " --executor " + executor);
      EXPECT_EQ(r.code, 2) << c.body << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
      EXPECT_NE(r.err.find(dir.file("bad.yaml")), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(c.key), std::string::npos) << r.err;
      EXPECT_FALSE(fs::exists(out)) << c.body;  // nothing planned, nothing submitted
    }
  }
}

// -o DIR naming an input, a folder whose top or points/ hold an input, or a node that is not a folder (issue 31):
// one line naming -o and the input, exit 2, before anything is written, every input as it was. Before, the
// spec saved as DIR/plan.json was replaced by the plan, and an input under DIR/points by a point's folder.
TEST(SweepCli, AnOutputFolderThatIsOrHoldsAnInputIsRefused) {
  test::TempDir dir;
  const std::string spec_text = "duration: 2\nvary:\n  seed: [1, 2]\n";
  fs::create_directories(dir.file("s/points"));
  for (const char* name : {"s/spec.yaml", "s/plan.json", "s/points/spec.yaml"})
    std::ofstream(dir.file(name)) << spec_text;
  const std::string log = dir.file("b/points/x.lcm");
  fs::create_directories(dir.file("b/points"));
  fs::copy_file(std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm", log);
  const auto sample_bytes = test::read_file(log);
  ASSERT_EQ(::mkfifo(dir.file("fifo").c_str(), 0600), 0);
  struct Case {
    std::string args, words;
  };
  const std::vector<Case> cases = {
      {"sweep " + dir.file("s/spec.yaml") + " -o " + dir.file("s/spec.yaml"), "is a regular file, not a folder"},
      {"sweep " + dir.file("s/plan.json") + " -o " + dir.file("s"),
       "-o " + dir.file("s") + " writes " + dir.file("s/plan.json") + ": is the input " + dir.file("s/plan.json")},
      {"sweep " + dir.file("s/points/spec.yaml") + " -o " + dir.file("s"),
       "the input " + dir.file("s/points/spec.yaml") + " lies in " + dir.file("s/points")},
      {"sweep " + dir.file("s/spec.yaml") + " -o " + dir.file("fifo"), "is a FIFO, not a folder"},
      {"batch diagnose " + log + " -o " + dir.file("b"), "the input " + log + " lies in " + dir.file("b/points")},
      {"batch diagnose " + log + " -o " + log, "is a regular file, not a folder"},
  };
  for (const auto& c : cases) {
    const auto r = test::driftlab(c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.words), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  for (const char* name : {"s/spec.yaml", "s/plan.json", "s/points/spec.yaml"}) {
    std::ifstream in(dir.file(name));
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), spec_text) << name;
  }
  EXPECT_EQ(test::read_file(log), sample_bytes);
  EXPECT_FALSE(fs::exists(dir.file("b/plan.json")));
  EXPECT_TRUE(fs::is_fifo(dir.file("fifo")));
  // A sweep's folder beside its spec, inside the spec's folder, is what everyone does: accepted.
  const auto ok = test::driftlab("sweep " + dir.file("s/spec.yaml") + " -o " + dir.file("s/out") + " --dry-run");
  EXPECT_EQ(ok.code, 0) << ok.err;
}

TEST(BatchCli, DiagnoseManyLogsRanked) {
  test::TempDir dir;
  // Three logs: two simulated (one with a bad IMU clock and lossy scans), and the sample log; given as a quoted
  // pattern and a file of paths.
  fs::create_directories(dir.file("logs"));
  std::ofstream(dir.file("bad.yaml")) << "streams:\n  IMU: {clock_offset_s: 0.08}\n  SCAN: {drop_probability: 0.2}\n"
                                         "  ODOM: {drop_probability: 0.1}\n";
  std::ofstream(dir.file("good.yaml")) << "streams: {}\n";
  ASSERT_EQ(test::driftlab("sim --duration 5 --faults " + dir.file("bad.yaml") + " -o " + dir.file("logs/bad.lcm")).code, 0);
  ASSERT_EQ(test::driftlab("sim --duration 5 --faults " + dir.file("good.yaml") + " -o " + dir.file("logs/good.lcm")).code, 0);
  std::ofstream(dir.file("list.txt")) << "# logs of the week\n" << std::string(DRIFTLAB_TEST_DATA) << "/sample.lcm\n";
  const std::string out = dir.file("batch");
  auto r = test::driftlab("batch diagnose '" + dir.file("logs/*.lcm") + "' @" + dir.file("list.txt") + " -o " + out + " --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["done"], 3);
  std::ifstream f(out + "/results.json");
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j["ranked"].size(), 3u);
  // The faulty log ranks first, its worst stream named.
  EXPECT_EQ(fs::path(j["ranked"][0]["log"].get<std::string>()).filename(), "bad.lcm") << j["ranked"].dump(1);
  EXPECT_NE(j["ranked"][0]["worst_stream"], "");
  EXPECT_GT(j["ranked"][0]["drops"].get<int>(), 0);
  EXPECT_TRUE(fs::exists(out + "/index.html"));
  EXPECT_TRUE(fs::exists(out + "/ranked.png"));
  // A log that is not there: one line, exit 2.
  r = test::driftlab("batch diagnose " + dir.file("nothing.lcm") + " -o " + dir.file("b2"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("nothing.lcm"), std::string::npos);
  // eval over logs that hold both trajectories (the simulator's odometry against its ground truth).
  r = test::driftlab("batch eval " + dir.file("logs/good.lcm") + " " + dir.file("logs/bad.lcm") +
                     " --est ODOM -o " + dir.file("evals") + " --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto rows = test::result_rows(dir.file("evals"));
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& row : rows) EXPECT_GT(row["ate_rmse"].get<double>(), 0) << row.dump();
}

/// A sweep over logs (a spec with `logs:` instead of a scenario): each log replayed with each point's faults
/// injected (`driftlab replay --inject`), diagnosed and scored; the table has the log, the varied value, and what
/// the diagnosis found: the IMU clock ahead (`offset_s.IMU`, the log's own 15 ms plus the injected offset) and the
/// odometry messages the injection dropped (`drops.ODOM`, `drops`).
TEST(SweepCli, SweepOverLogsInjectsEachPointsFaults) {
  test::TempDir dir;
  fs::create_directories(dir.file("logs"));
  for (int seed : {1, 2}) {
    // 12 s: the clock fit needs 10 s of data. The default scenario's IMU clock is 15 ms ahead.
    const auto r = test::driftlab("sim --duration 12 --seed " + std::to_string(seed) + " -o " +
                                  dir.file("logs/run" + std::to_string(seed) + ".lcm"));
    ASSERT_EQ(r.code, 0) << r.err;
  }
  const std::string spec = dir.file("logs.yaml");
  std::ofstream(spec) << "name: over-logs\n"
                         "logs: [\"logs/*.lcm\"]\n"  // relative to the spec
                         "modules: estimator\n"
                         "settings:\n  estimator: {window_s: 0}\n"
                         "faults: {streams: {ODOM: {drop_probability: 0.3}}}\n"
                         "eval: {gt: GROUND_TRUTH, est: EKF_ODOM, align: posyaw}\n"
                         "pipeline: [replay, diagnose, eval]\n"
                         "vary:\n"
                         "  faults.IMU.clock_offset_s: [0, 0.05]\n";
  const std::string out = dir.file("sweep");
  auto r = test::driftlab("sweep " + spec + " -o " + out + " -j 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["done"], 4);
  const auto rows = test::result_rows(out);
  ASSERT_EQ(rows.size(), 4u);
  std::map<std::string, std::map<double, nlohmann::json>> by_log;
  for (const auto& row : rows) {
    SCOPED_TRACE(row.dump());
    ASSERT_EQ(row["status"], "done");
    const std::string log = row["log"];
    EXPECT_EQ(fs::path(log).parent_path(), fs::path(dir.file("logs")));
    const double injected = row["faults.IMU.clock_offset_s"].get<double>();
    by_log[log][injected] = row;
    // The IMU clock found ahead by the log's 15 ms and the injected offset (to within the fastest delivery).
    ASSERT_TRUE(row["offset_s.IMU"].is_number());
    EXPECT_NEAR(row["offset_s.IMU"].get<double>(), 0.015 + injected, 0.001);
    // The replay dropped about 30% of the 600 odometry messages; the diagnosis counted them from seq.
    ASSERT_TRUE(row["drops.ODOM"].is_number());
    EXPECT_NEAR(row["drops.ODOM"].get<double>(), 180, 50);
    EXPECT_GE(row["drops"].get<double>(), row["drops.ODOM"].get<double>());
    EXPECT_GT(row["ate_rmse"].get<double>(), 0);
  }
  ASSERT_EQ(by_log.size(), 2u);
  for (const auto& [log, points] : by_log) {
    ASSERT_EQ(points.size(), 2u) << log;
    // Each point's faults were its own: the injected 50 ms shows in its row alone.
    EXPECT_NEAR(points.at(0.05)["offset_s.IMU"].get<double>() - points.at(0.0)["offset_s.IMU"].get<double>(), 0.05,
                0.0005)
        << log;
    EXPECT_NE(points.at(0.05)["id"], points.at(0.0)["id"]);
  }
  // The CSV names the log of each row.
  std::ifstream csv(out + "/results.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("id,status,attempts,log,faults.IMU.clock_offset_s,", 0), 0u) << header;
  EXPECT_NE(header.find(",offset_s.IMU"), std::string::npos) << header;
  EXPECT_NE(header.find(",drops.ODOM"), std::string::npos) << header;
}

/// A setting of a module's section (slam's 2d) varied over a log, with the section's other settings fixed in the
/// spec: each point's replay reads both from one `2d` map (a flat `2d.keyframe_distance` key was refused), and the
/// SLAM makes a keyframe every 0.2 m in one point and every 1 m in the other.
TEST(SweepCli, ASectionsSettingVariesTheModule) {
  test::TempDir dir;
  fs::create_directories(dir.file("logs"));
  auto r = test::driftlab("sim --duration 12 --seed 1 -o " + dir.file("logs/run.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string spec = dir.file("keyframes.yaml");
  std::ofstream(spec) << R"(name: keyframes
logs: ["logs/*.lcm"]
modules: slam
settings: {slam: {backend: 2d, 2d: {loop_closure: false}}}
pipeline: [replay]
vary: {slam.2d.keyframe_distance: [0.2, 1.0]}
)";
  const std::string out = dir.file("sweep");
  r = test::driftlab("sweep " + spec + " -o " + out + " -j 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  std::map<double, double> keyframes;  // keyframe_distance -> keyframes made
  for (const auto& row : test::result_rows(out)) {
    ASSERT_EQ(row["status"], "done") << row.dump();
    std::ifstream f(out + "/points/" + row["id"].get<std::string>() + "/replay.json");
    const auto replay = nlohmann::json::parse(f);
    for (const auto& m : replay["modules"]) {
      if (m["name"] != "slam") continue;
      EXPECT_EQ(m["metrics"]["loop_tests"], 0) << m.dump();  // the fixed setting of the same section holds
      keyframes[row["slam.2d.keyframe_distance"].get<double>()] = m["metrics"]["keyframes"].get<double>();
    }
  }
  ASSERT_EQ(keyframes.size(), 2u);
  // About 4 m travelled in 12 s: a keyframe each 0.2 m makes four times as many as one each metre, and more.
  EXPECT_GT(keyframes[0.2], 3 * keyframes[1.0]);
}

/// `driftlab batch report`: each log diagnosed and given its report page, the batch ranked worst first.
TEST(BatchCli, ReportWritesEachLogsPageAndRanksThem) {
  test::TempDir dir;
  fs::create_directories(dir.file("logs"));
  std::ofstream(dir.file("bad.yaml")) << "streams:\n  IMU: {clock_offset_s: 0.08}\n  SCAN: {drop_probability: 0.2}\n";
  std::ofstream(dir.file("good.yaml")) << "streams: {}\n";
  for (const char* name : {"good", "bad"}) {
    const auto r = test::driftlab("sim --duration 5 --faults " + dir.file(std::string(name) + ".yaml") + " -o " +
                                  dir.file(std::string("logs/") + name + ".lcm"));
    ASSERT_EQ(r.code, 0) << r.err;
  }
  const std::string out = dir.file("reports");
  auto r = test::driftlab("batch report " + dir.file("logs/good.lcm") + " " + dir.file("logs/bad.lcm") + " -o " + out +
                          " --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["done"], 2);
  const auto rows = test::result_rows(out);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& row : rows) {
    SCOPED_TRACE(row.dump());
    ASSERT_EQ(row["status"], "done");
    // The page of each log, where the row says, made from the point's own diagnosis.
    const std::string page = row["report"];
    EXPECT_TRUE(fs::exists(page));
    EXPECT_GT(fs::file_size(page), 1000u);
    const fs::path point = fs::path(page).parent_path().parent_path();
    EXPECT_TRUE(fs::exists(point / "diagnosis.json"));
    std::ifstream in(page);
    std::stringstream html;
    html << in.rdbuf();
    EXPECT_NE(html.str().find(fs::path(row["log"].get<std::string>()).filename().string()), std::string::npos);
  }
  std::ifstream f(out + "/results.json");
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j["ranked"].size(), 2u);
  EXPECT_EQ(fs::path(j["ranked"][0]["log"].get<std::string>()).filename(), "bad.lcm") << j["ranked"].dump(1);
  EXPECT_EQ(fs::path(j["ranked"][1]["log"].get<std::string>()).filename(), "good.lcm") << j["ranked"].dump(1);
  EXPECT_TRUE(fs::exists(out + "/index.html"));
}

}  // namespace
}  // namespace driftlab
