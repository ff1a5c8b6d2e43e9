// `driftlab sweep --executor slurm` on a real Slurm: run by tests/slurm_run.sh, which starts a single-node cluster
// (munged, slurmctld, slurmd) for this test only and stops it afterwards. The tiny sweep is submitted as one job
// array, one task's work is killed mid-run (its stage process, SIGKILL, as the OOM killer would), the task requeues
// itself and finishes, and the merged table equals the local executor's for the same seeds.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "tests/batch/sweep_util.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// The child processes of pid (Linux /proc).
std::vector<pid_t> children_of(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/task/" + std::to_string(pid) + "/children");
  std::vector<pid_t> out;
  for (pid_t c; in >> c;) out.push_back(c);
  return out;
}

/// Kills, with SIGKILL, the stage process of a point that some task is running; returns the point's id.
std::string kill_one_running_stage(const std::string& out, Clock::time_point deadline) {
  while (Clock::now() < deadline) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(out + "/points", ec)) {
      if (!fs::exists(e.path() / "running.json") || fs::exists(e.path() / "result.json")) continue;
      std::ifstream f(e.path() / "running.json");
      nlohmann::json running;
      try {
        running = nlohmann::json::parse(f);
      } catch (const nlohmann::json::exception&) {
        continue;
      }
      if (!running.contains("slurm_job")) continue;
      for (pid_t child : children_of(running["pid"].get<pid_t>())) {
        if (kill(child, SIGKILL) == 0) return e.path().filename().string();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return "";
}

TEST(SweepSlurm, JobArrayWithRequeueGivesTheLocalTable) {
  ASSERT_NE(std::getenv("SLURM_CONF"), nullptr) << "run through tests/slurm_run.sh";
  test::TempDir dir;
  const std::string spec = test::write_tiny_spec(dir);

  // The reference: the local executor.
  auto r = test::driftlab("sweep " + spec + " -o " + dir.file("local") + " -j 2 --json");
  ASSERT_EQ(r.code, 0) << r.err;

  // Submission returns with the job id; the tasks run on the cluster.
  const std::string out = dir.file("slurm");
  r = test::driftlab("sweep " + spec + " -o " + out + " --executor slurm --max-parallel 2 --requeue 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto submitted = nlohmann::json::parse(r.out);
  const std::string job = submitted["job_id"];
  EXPECT_FALSE(job.empty());
  EXPECT_EQ(submitted["submitted"], 4);
  EXPECT_TRUE(fs::exists(out + "/slurm/array-0.sh"));

  const auto deadline = Clock::now() + std::chrono::seconds(200);
  const std::string killed = kill_one_running_stage(out, deadline);
  ASSERT_FALSE(killed.empty()) << "no task was caught running";

  nlohmann::json status;
  while (Clock::now() < deadline) {
    r = test::driftlab("sweep status " + out + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    status = nlohmann::json::parse(r.out);
    if (status["done"] == 4) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  ASSERT_EQ(status["done"], 4) << status.dump(1);
  EXPECT_EQ(status["slurm_jobs"], nlohmann::json::array({job}));

  // The killed point ran twice: the task requeued itself (its log says so) and the second attempt finished.
  std::ifstream attempts(out + "/points/" + killed + "/attempts");
  int n = 0;
  attempts >> n;
  EXPECT_EQ(n, 2) << killed;
  std::string logs;
  for (const auto& e : fs::directory_iterator(out + "/slurm/logs")) {
    std::ifstream f(e.path());
    std::stringstream s;
    s << f.rdbuf();
    logs += s.str();
  }
  EXPECT_NE(logs.find("point " + killed + " failed (exit 1); requeueing, restart 1 of 2"), std::string::npos) << logs;
  EXPECT_NE(logs.find("restart 1)"), std::string::npos) << logs;

  // Collected from the folder alone: the same numbers as the local executor's.
  r = test::driftlab("sweep collect " + out + " --no-plots");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::metrics_by_id(out), test::metrics_by_id(dir.file("local")));
}

}  // namespace
}  // namespace driftlab
