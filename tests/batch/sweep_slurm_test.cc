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

/// What a Slurm command printed (stdout), "" when it failed.
std::string slurm(const std::string& command) {
  const auto r = test::run_capture(command);
  return r.code == 0 ? r.out : "";
}

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

/// One task of the job array that Slurm has running ("JOB_TASK"), waiting up to the deadline; "" if none.
std::string running_task(const std::string& job, Clock::time_point deadline) {
  while (Clock::now() < deadline) {
    std::istringstream tasks(slurm("squeue -h -j " + job + " -t R -o %i"));
    std::string task;
    if (tasks >> task) return task;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return "";
}

/// Waits until `sweep status` counts every point done (or the deadline); returns the last status.
nlohmann::json wait_done(const std::string& command, const std::string& out, int points, Clock::time_point deadline) {
  nlohmann::json status;
  while (Clock::now() < deadline) {
    const auto r = test::driftlab(command + " status " + out + " --json");
    if (r.code != 0) return status;
    status = nlohmann::json::parse(r.out);
    if (status["done"] == points) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  return status;
}

/// The point a task ran: its log's first line names it.
std::string point_of_task(const std::string& out, const std::string& task) {
  const std::string log = read_text(out + "/slurm/logs/" + task + ".out");
  const size_t at = log.find(": point ");
  return at == std::string::npos ? "" : log.substr(at + 8, 12);
}

/// Waits until the point a task runs has started its attempt (its running marker is there); returns the point.
std::string started_point(const std::string& out, const std::string& task, Clock::time_point deadline) {
  while (Clock::now() < deadline) {
    std::string id = point_of_task(out, task);
    if (!id.empty() && fs::exists(out + "/points/" + id + "/running.json")) return id;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
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

  // Submission returns with the job id; the tasks run on the cluster. --slurm-opt reaches sbatch as it is: the
  // comment shows in Slurm's record of the job, and the command submitted is kept beside its answer.
  const std::string out = dir.file("slurm");
  r = test::driftlab("sweep " + spec + " -o " + out +
                     " --executor slurm --max-parallel 2 --requeue 2 --slurm-opt=--comment=driftlab-tiny-test --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto submitted = nlohmann::json::parse(r.out);
  const std::string job = submitted["job_id"];
  EXPECT_FALSE(job.empty());
  EXPECT_EQ(submitted["submitted"], 4);
  EXPECT_TRUE(fs::exists(out + "/slurm/array-0.sh"));
  EXPECT_NE(slurm("scontrol show job " + job).find("Comment=driftlab-tiny-test"), std::string::npos);
  const std::string command = read_text(out + "/slurm/array-0.sbatch.cmd");
  EXPECT_NE(command.find("'--array=0-3%2'"), std::string::npos) << command;
  EXPECT_NE(command.find("'--comment=driftlab-tiny-test' '" + out + "/slurm/array-0.sh'"), std::string::npos)
      << command;

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

/// The task itself killed, not the work inside it. Slurm requeues a task its node failed under (sbatch --requeue):
/// the node is taken down while a task runs (`scontrol update State=DOWN`, as slurmctld does when a node stops
/// answering); the task is killed, requeued by Slurm (its Restarts count), runs again when the node is back and the
/// point ends done. Slurm never requeues a task that was cancelled: `scancel --signal=KILL` of a running task
/// leaves its point failed (interrupted), and running the sweep again submits that point alone and finishes it.
/// docs/batch.md says what is and is not covered.
TEST(SweepSlurm, TasksKilledOnTheClusterAreRequeuedOrResubmitted) {
  ASSERT_NE(std::getenv("SLURM_CONF"), nullptr) << "run through tests/slurm_run.sh";
  test::TempDir dir;
  const std::string spec = test::write_tiny_spec(dir);
  const std::string node = slurm("hostname -s").substr(0, slurm("hostname -s").find('\n'));
  const auto deadline = Clock::now() + std::chrono::seconds(240);

  // A node failure: Slurm kills the task and requeues it.
  const std::string down = dir.file("down");
  auto r = test::driftlab("sweep " + spec + " -o " + down + " --executor slurm --max-parallel 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const std::string job = nlohmann::json::parse(r.out)["job_id"];
  const std::string task = running_task(job, deadline);
  ASSERT_FALSE(task.empty()) << "no task was caught running";
  const std::string requeued = started_point(down, task, deadline);
  ASSERT_FALSE(requeued.empty()) << "the task's point did not start";
  ASSERT_EQ(test::run("scontrol update NodeName=" + node + " State=DOWN Reason=driftlab-test"), 0);
  std::string record;
  for (int i = 0; i < 100 && record.find("Restarts=1") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    record = slurm("scontrol show job " + task);
  }
  EXPECT_NE(record.find("Restarts=1"), std::string::npos) << record;  // requeued by Slurm, not by the task
  (void)test::run("scontrol update NodeName=" + node + " State=RESUME >/dev/null 2>&1");  // ReturnToService may have
  auto status = wait_done("sweep", down, 4, deadline);
  ASSERT_EQ(status["done"], 4) << status.dump(1);
  std::ifstream attempts(down + "/points/" + requeued + "/attempts");
  int n = 0;
  attempts >> n;
  EXPECT_EQ(n, 2) << requeued;
  const std::string log = read_text(down + "/slurm/logs/" + task + ".out");
  EXPECT_NE(log.find("DUE TO NODE FAILURE"), std::string::npos) << log;
  EXPECT_NE(log.find("point " + requeued + " (restart 1)"), std::string::npos) << log;

  // A task cancelled with SIGKILL: not requeued; the point is failed until the sweep is run again.
  const std::string cancelled = dir.file("cancelled");
  r = test::driftlab("sweep " + spec + " -o " + cancelled + " --executor slurm --max-parallel 2 --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const std::string job2 = nlohmann::json::parse(r.out)["job_id"];
  const std::string task2 = running_task(job2, deadline);
  ASSERT_FALSE(task2.empty()) << "no task was caught running";
  ASSERT_FALSE(started_point(cancelled, task2, deadline).empty()) << "the task's point did not start";
  ASSERT_EQ(test::run("scancel --signal=KILL --full " + task2), 0);
  nlohmann::json first;
  while (Clock::now() < deadline) {
    first = nlohmann::json::parse(test::driftlab("sweep status " + cancelled + " --json").out);
    if (first["done"].get<int>() + first["failed"].get<int>() == 4 && first["running"] == 0 &&
        slurm("squeue -h -j " + job2).empty()) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  EXPECT_NE(slurm("scontrol show job " + task2).find("JobState=CANCELLED"), std::string::npos);
  EXPECT_NE(slurm("scontrol show job " + task2).find("Restarts=0"), std::string::npos);
  ASSERT_EQ(first["done"], 3) << first.dump(1);
  ASSERT_EQ(first["failed"], 1) << first.dump(1);
  r = test::driftlab("sweep " + spec + " -o " + cancelled + " --executor slurm --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["submitted"], 1);
  status = wait_done("sweep", cancelled, 4, deadline);
  ASSERT_EQ(status["done"], 4) << status.dump(1);
  // Both give the local executor's numbers.
  for (const auto& out : {down, cancelled}) {
    ASSERT_EQ(test::driftlab("sweep collect " + out + " --no-plots").code, 0);
  }
  EXPECT_EQ(test::metrics_by_id(down), test::metrics_by_id(cancelled));
}

/// `driftlab batch diagnose` as a job array: one task a log, the same table as the local executor's.
TEST(BatchSlurm, DiagnoseManyLogsAsAJobArray) {
  ASSERT_NE(std::getenv("SLURM_CONF"), nullptr) << "run through tests/slurm_run.sh";
  test::TempDir dir;
  fs::create_directories(dir.file("logs"));
  std::ofstream(dir.file("bad.yaml")) << "streams:\n  IMU: {clock_offset_s: 0.08}\n  SCAN: {drop_probability: 0.2}\n";
  for (const char* name : {"good", "bad"}) {
    const std::string faults = std::string(name) == "bad" ? " --faults " + dir.file("bad.yaml") : "";
    ASSERT_EQ(
        test::driftlab("sim --duration 5" + faults + " -o " + dir.file(std::string("logs/") + name + ".lcm")).code, 0);
  }
  const std::string logs = dir.file("logs/good.lcm") + " " + dir.file("logs/bad.lcm");
  auto r = test::driftlab("batch diagnose " + logs + " -o " + dir.file("local") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::driftlab("batch diagnose " + logs + " -o " + dir.file("slurm") + " --executor slurm --json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["submitted"], 2);
  const auto status = wait_done("batch", dir.file("slurm"), 2, Clock::now() + std::chrono::seconds(120));
  ASSERT_EQ(status["done"], 2) << status.dump(1);
  ASSERT_EQ(test::driftlab("batch collect " + dir.file("slurm") + " --no-plots").code, 0);
  EXPECT_EQ(test::metrics_by_id(dir.file("slurm")), test::metrics_by_id(dir.file("local")));
  std::ifstream f(dir.file("slurm") + "/results.json");
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j["ranked"].size(), 2u);
  EXPECT_EQ(fs::path(j["ranked"][0]["log"].get<std::string>()).filename(), "bad.lcm");
}

}  // namespace
}  // namespace driftlab
