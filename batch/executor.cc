#include "batch/executor.h"

#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "batch/store.h"
#include "core/process.h"
#include "core/text_file.h"
#include "core/wall_clock.h"

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

/// 'text' quoted for sh.
std::string sh_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class LocalExecutor : public Executor {
 public:
  explicit LocalExecutor(LocalOptions o) : o_(std::move(o)) {
    if (o_.jobs <= 0) o_.jobs = usable_cpus();
  }

  Result<ExecutionSummary> execute(const std::string& dir, const std::vector<std::string>& ids) override {
    ExecutionSummary sum;
    const fs::path logs = fs::path(dir) / "logs";
    std::error_code ec;
    fs::create_directories(logs, ec);
    if (ec) return Error{logs.string() + ": cannot create: " + ec.message(), ErrorCode::kCannotWrite};
    std::deque<std::string> queue(ids.begin(), ids.end());
    std::map<std::string, int> tries;
    std::map<pid_t, std::string> running;
    const size_t total = ids.size();
    const Stopwatch since_start;
    Stopwatch since_draw;
    bool stopping = false;
    bool drawn = false;
    auto draw = [&](bool force) {
      if (!o_.progress) return;
      if (!force && drawn && since_draw.seconds() < 0.2) return;
      since_draw.restart();
      const double elapsed = since_start.seconds();
      const size_t finished = sum.done + sum.failed;
      constexpr int kWidth = 24;
      const int filled = total > 0 ? static_cast<int>(kWidth * finished / total) : kWidth;
      std::string bar(static_cast<size_t>(filled), '#');
      bar.resize(kWidth, '.');
      char eta[48] = "";
      if (finished > 0 && finished < total) {
        std::snprintf(eta, sizeof(eta), ", ~%.0f s left", elapsed / static_cast<double>(finished) * static_cast<double>(total - finished));
      }
      std::fprintf(stderr, "\r\033[K[%s] %zu/%zu points done, %zu running, %zu failed, %.0f s%s", bar.c_str(), sum.done,
                   total, running.size(), sum.failed, elapsed, eta);
      std::fflush(stderr);
      drawn = true;
    };
    while (!queue.empty() || !running.empty()) {
      if (!stopping && o_.stop != nullptr && o_.stop->load()) {
        stopping = true;
        for (const auto& [pid, id] : running) ::kill(pid, SIGTERM);
      }
      while (!stopping && !queue.empty() && static_cast<int>(running.size()) < o_.jobs) {
        const std::string id = queue.front();
        queue.pop_front();
        ++tries[id];
        const pid_t pid = start_process(o_.command(id), (logs / (id + ".out")).string(), (logs / (id + ".err")).string());
        if (pid < 0) return Error{"cannot start " + o_.command(id).front()};
        running[pid] = id;
      }
      draw(false);
      if (running.empty()) break;  // stopping, and every running point has ended
      int status = 0;
      const pid_t pid = ::waitpid(-1, &status, WNOHANG);
      if (pid <= 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        continue;
      }
      auto it = running.find(pid);
      if (it == running.end()) continue;
      const std::string id = it->second;
      running.erase(it);
      const int code = exit_code_of(status);
      if (code == 0 && is_done(dir, id)) {
        ++sum.done;
      } else if (stopping) {
        ++sum.not_started;
      } else if (tries[id] <= o_.retries) {
        queue.push_back(id);
      } else {
        ++sum.failed;
        if (o_.progress && drawn) std::fprintf(stderr, "\r\033[K");
        const std::string why = read_file((logs / (id + ".err")).string());
        std::fprintf(stderr, "%s", why.empty() ? ("driftlab: point " + id + " failed (exit " + std::to_string(code) + ")\n").c_str() : why.c_str());
      }
    }
    sum.not_started += queue.size();
    sum.interrupted = stopping;
    if (o_.progress && drawn) {
      draw(true);
      std::fprintf(stderr, "\n");
    }
    return sum;
  }

 private:
  LocalOptions o_;
};

class SlurmExecutor : public Executor {
 public:
  explicit SlurmExecutor(SlurmOptions o) : o_(std::move(o)) {}

  Result<ExecutionSummary> execute(const std::string& dir_in, const std::vector<std::string>& ids) override {
    ExecutionSummary sum;
    if (ids.empty()) return sum;
    const fs::path dir = fs::absolute(dir_in);
    const fs::path slurm = dir / "slurm";
    std::error_code ec;
    fs::create_directories(slurm / "logs", ec);
    if (ec) return Error{slurm.string() + ": cannot create: " + ec.message(), ErrorCode::kCannotWrite};
    int k = 0;
    while (fs::exists(slurm / ("array-" + std::to_string(k) + ".txt"))) ++k;
    const std::string stem = "array-" + std::to_string(k);
    std::string list;
    for (const auto& id : ids) list += id + "\n";
    if (Status s = write_file_atomically((slurm / (stem + ".txt")).string(), list, kSynced); !s) return s.error();

    const std::string script = (slurm / (stem + ".sh")).string();
    std::ostringstream sh;
    sh << "#!/bin/sh\n"
       << "# Written by driftlab: task N of this job array runs the point on line N+1 of " << stem << ".txt;\n"
       << "# a task that fails requeues itself up to " << o_.requeue << " times (bad input, exit 2, is not retried).\n"
       << "id=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " << sh_quote((slurm / (stem + ".txt")).string()) << ")\n"
       << "echo \"driftlab: task ${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID} on $(hostname): point $id"
       << " (restart ${SLURM_RESTART_COUNT:-0})\"\n"
       << sh_quote(o_.driftlab) << " " << o_.point_flag << " \"$id\" -o " << sh_quote(dir.string()) << "\n"
       << "rc=$?\n"
       << "restarts=${SLURM_RESTART_COUNT:-0}\n"
       << "if [ \"$rc\" -ne 0 ] && [ \"$rc\" -ne 2 ] && [ \"$restarts\" -lt " << o_.requeue << " ]; then\n"
       << "  echo \"driftlab: point $id failed (exit $rc); requeueing, restart $((restarts + 1)) of " << o_.requeue
       << "\" >&2\n"
       << "  scontrol requeue \"${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\"\n"
       << "fi\n"
       << "exit \"$rc\"\n";
    if (Status s = write_file_atomically(script, sh.str(), kSynced); !s) return s.error();
    fs::permissions(script, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add, ec);

    std::string array = "--array=0-" + std::to_string(ids.size() - 1);
    if (o_.max_parallel > 0) array += "%" + std::to_string(o_.max_parallel);
    std::vector<std::string> argv = {o_.sbatch, "--parsable", "--job-name=" + o_.job_name, array,
                                     "--output=" + (slurm / "logs" / "%A_%a.out").string(), "--open-mode=append",
                                     "--requeue", "--chdir=" + dir.string()};
    argv.insert(argv.end(), o_.slurm_options.begin(), o_.slurm_options.end());
    argv.push_back(script);
    // The command as submitted, beside its answer: what was asked of Slurm (the --slurm-opt options among it) can
    // be read and run again by hand.
    std::string command;
    for (const auto& a : argv) command += (command.empty() ? "" : " ") + sh_quote(a);
    if (Status s = write_file_atomically((slurm / (stem + ".sbatch.cmd")).string(), command + "\n", kSynced); !s) {
      return s.error();
    }
    const std::string out = (slurm / (stem + ".sbatch.out")).string(), err = (slurm / (stem + ".sbatch.err")).string();
    const int code = run_process(argv, out, err);
    if (code == 127) return Error{o_.sbatch + ": cannot run (is Slurm installed here? docs/batch.md)"};
    if (code != 0) {
      std::string why = read_file(err);
      while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
      if (const size_t nl = why.rfind('\n'); nl != std::string::npos) why = why.substr(nl + 1);
      fs::remove(slurm / (stem + ".txt"), ec);
      return Error{"sbatch exited with " + std::to_string(code) + (why.empty() ? "" : ": " + why)};
    }
    std::string job = read_file(out);
    job = job.substr(0, job.find_first_of(";\n"));
    sum.job_id = job;
    std::ofstream jobs(slurm / "jobs", std::ios::app);
    jobs << job << " " << stem << " " << ids.size() << "\n";
    return sum;
  }

 private:
  SlurmOptions o_;
};

}  // namespace

std::unique_ptr<Executor> make_local_executor(LocalOptions options) {
  return std::make_unique<LocalExecutor>(std::move(options));
}

std::unique_ptr<Executor> make_slurm_executor(SlurmOptions options) {
  return std::make_unique<SlurmExecutor>(std::move(options));
}

int usable_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0) return 1;
  return std::max(1, CPU_COUNT(&set));
}

std::vector<std::string> slurm_jobs(const std::string& dir) {
  std::vector<std::string> out;
  std::ifstream in(fs::path(dir) / "slurm" / "jobs");
  for (std::string line; std::getline(in, line);) {
    const std::string job = line.substr(0, line.find(' '));
    if (!job.empty()) out.push_back(job);
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> slurm_queue(const std::vector<std::string>& jobs) {
  std::vector<std::pair<std::string, std::string>> out;
  if (jobs.empty()) return out;
  std::string list;
  for (const auto& j : jobs) list += (list.empty() ? "" : ",") + j;
  char tmpl[] = "/tmp/driftlab-squeue-XXXXXX";
  const int fd = ::mkstemp(tmpl);
  if (fd < 0) return out;
  ::close(fd);
  const int code = run_process({"squeue", "-h", "-r", "-j", list, "-o", "%i %T"}, tmpl, "/dev/null");
  if (code == 0) {
    std::ifstream in(tmpl);
    for (std::string id, state; in >> id >> state;) out.emplace_back(id, state);
  }
  std::remove(tmpl);
  return out;
}

}  // namespace driftlab::batch
