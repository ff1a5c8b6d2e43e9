#include "batch/session.h"

#include <sys/stat.h>

#include <cctype>
#include <filesystem>
#include <sstream>

#include "batch/spec.h"
#include "core/number_text.h"
#include "core/process.h"
#include "core/same_file.h"
#include "core/text_file.h"
#include "core/wall_clock.h"

namespace driftlab::batch {

namespace fs = std::filesystem;

std::vector<std::string> sweep_files(const std::string& dir) {
  std::vector<std::string> files;
  for (const char* name : {"plan.json", "results.csv", "results.json", "index.html"}) {
    files.push_back((fs::path(dir) / name).string());
  }
  return files;
}

Status check_sweep_dir(const std::string& dir, const std::vector<std::string>& inputs) {
  std::error_code ec;
  if (fs::exists(fs::symlink_status(dir, ec)) && !fs::is_directory(dir, ec)) {
    struct stat st {};
    const char* kind = ::stat(dir.c_str(), &st) == 0 ? internal::node_kind(st) : "a dangling link";
    return Error{"-o " + dir + ": is " + kind + ", not a folder: give the sweep's folder (made if absent)"};
  }
  if (Status s = refuse_same_file(dir, inputs, "-o", OutputKind::kFolder); !s) return s;
  for (const std::string& file : sweep_files(dir)) {
    if (Status s = refuse_same_file(file, inputs, "-o " + dir + " writes"); !s) return s;
  }
  const fs::path points = internal::resolved((fs::path(dir) / "points").string());
  for (const auto& in : inputs) {
    if (in.empty()) continue;
    if (internal::is_within(internal::resolved(in), points)) {
      return Error{"-o " + dir + ": the input " + in + " lies in " + (fs::path(dir) / "points").string() +
                   ", where the points are written: give another folder"};
    }
  }
  return {};
}

Result<std::vector<std::string>> batch_logs(const std::vector<std::string>& items, const std::string& list) {
  std::vector<std::string> out;
  auto add = [&](const std::string& item) -> Status {
    if (!is_pattern(item)) {
      out.push_back(item);
      return {};
    }
    auto found = expand_pattern(item);  // a pattern the shell left alone (quoted, or no match)
    if (found.empty()) return Error{item + ": matches no file"};
    out.insert(out.end(), found.begin(), found.end());
    return {};
  };
  auto read_list = [&](const std::string& path) -> Status {
    auto text = read_text_file(path, "list of logs");
    if (!text) return text.error();
    std::istringstream in(*text);
    for (std::string line; std::getline(in, line);) {
      line.erase(0, line.find_first_not_of(" \t"));
      line.erase(line.find_last_not_of(" \t\r") + 1);
      if (line.empty() || line[0] == '#') continue;
      if (fs::path(line).is_relative()) line = (fs::path(path).parent_path() / line).string();
      if (Status s = add(line); !s) return Error{path + ": " + s.message()};
    }
    return {};
  };
  if (!list.empty()) {
    if (Status s = read_list(list); !s) return s.error();
  }
  for (const auto& item : items) {
    Status s = item.size() > 1 && item[0] == '@' ? read_list(item.substr(1)) : add(item);
    if (!s) return s.error();
  }
  return out;
}

Result<std::string> write_tables(const std::string& dir, const Plan& plan) {
  const Table t = merge_results(dir, plan);
  nlohmann::json j = {{"name", plan.spec.name}, {"kind", plan.spec.kind}, {"columns", t.columns}, {"rows", t.rows}};
  j["varied"] = nlohmann::json::array();
  for (const auto& p : plan.spec.vary) j["varied"].push_back(p.key);
  j["stages"] = nlohmann::json::array();
  for (Stage s : plan.spec.stages) j["stages"].push_back(stage_name(s));
  if (plan.spec.kind == "batch" || !plan.spec.logs.empty()) j["ranked"] = rank_batch(t);
  const std::string json_path = (fs::path(dir) / "results.json").string();
  if (Status s = write_file_atomically((fs::path(dir) / "results.csv").string(), table_csv(t), kSynced); !s)
    return s.error();
  if (Status s = write_file_atomically(json_path, j.dump(1) + "\n", kSynced); !s) return s.error();
  return json_path;
}

SweepState sweep_state(const std::string& dir, const Plan& plan, bool with_slurm) {
  SweepState s;
  s.points = plan.points.size();
  for (const auto& p : plan.points) {
    PointStatus st = point_status(dir, p.id);
    ++s.by_state[st.state];
    if (st.state == PointState::kFailed) s.failed.push_back(std::move(st));
  }
  if (with_slurm) {
    s.slurm_jobs = slurm_jobs(dir);
    s.slurm_tasks = slurm_queue(s.slurm_jobs);
  }
  return s;
}

nlohmann::json to_json(const SweepState& s, const std::string& dir) {
  nlohmann::json j = {{"dir", dir},
                      {"points", s.points},
                      {"done", s.count(PointState::kDone)},
                      {"running", s.count(PointState::kRunning)},
                      {"failed", s.count(PointState::kFailed)},
                      {"pending", s.count(PointState::kPending)},
                      {"slurm_jobs", s.slurm_jobs}};
  j["slurm_tasks"] = nlohmann::json::object();
  for (const auto& [id, state] : s.slurm_tasks) j["slurm_tasks"][id] = state;
  j["failures"] = nlohmann::json::array();
  for (const auto& f : s.failed)
    j["failures"].push_back({{"id", f.id}, {"attempts", f.attempts}, {"record", f.record}});
  return j;
}

std::string state_text(const SweepState& s, const std::string& dir) {
  std::ostringstream out;
  out << dir << ": " << s.points << " points: " << s.count(PointState::kDone) << " done, "
      << s.count(PointState::kRunning) << " running, " << s.count(PointState::kFailed) << " failed, "
      << s.count(PointState::kPending) << " pending\n";
  for (const auto& f : s.failed) {
    out << "  failed " << f.id << " (attempt " << f.attempts
        << "): " << (f.record.is_object() ? f.record.value("error", "") : "") << "\n";
  }
  if (!s.slurm_jobs.empty()) {
    std::map<std::string, size_t> states;
    for (const auto& [id, state] : s.slurm_tasks) ++states[state];
    std::string jobs, counts;
    for (const auto& j : s.slurm_jobs) jobs += (jobs.empty() ? "" : ",") + j;
    for (const auto& [state, k] : states) counts += (counts.empty() ? "" : ", ") + std::to_string(k) + " " + state;
    out << "slurm jobs " << jobs << ": " << (counts.empty() ? "none in the queue" : counts) << "\n";
  }
  return out.str();
}

std::vector<std::string> pending_points(const std::string& dir, const Plan& plan) {
  std::vector<std::string> pending;
  for (const auto& p : plan.points) {
    if (!is_done(dir, p.id)) pending.push_back(p.id);
  }
  return pending;
}

std::string dry_run_text(const std::string& dir, const Plan& plan) {
  std::string out;
  for (const auto& p : plan.points) {
    out += p.id + " " + (is_done(dir, p.id) ? "done   " : "pending");
    for (const auto& [k, v] : p.params) out += " " + k + "=" + v.text;
    out += "\n";
  }
  return out;
}

Result<LocalRun> run_locally(const std::string& dir, const Plan& plan, const RunOptions& o) {
  const std::vector<std::string> pending = pending_points(dir, plan);
  if (Status s = save_plan(dir, plan); !s) return s.error();
  LocalOptions lo;
  lo.jobs = o.jobs;
  lo.retries = o.retries;
  lo.progress = o.progress;
  lo.stop = o.stop;
  std::vector<std::string> flag_words;
  std::istringstream words(o.point_flag);
  for (std::string w; words >> w;) flag_words.push_back(w);
  lo.command = [exe = o.driftlab, abs_dir = fs::absolute(dir).string(), flag_words](const std::string& id) {
    std::vector<std::string> argv = {exe};
    argv.insert(argv.end(), flag_words.begin(), flag_words.end());
    argv.insert(argv.end(), {id, "-o", abs_dir});
    return argv;
  };
  const Stopwatch running;
  auto r = make_local_executor(lo)->execute(dir, pending);
  if (!r) return r.error();
  return LocalRun{*r, plan.points.size() - pending.size(), running.seconds(), lo.jobs > 0 ? lo.jobs : usable_cpus()};
}

Result<Submission> submit_to_slurm(const std::string& dir, const Plan& plan, const RunOptions& o) {
  const std::vector<std::string> pending = pending_points(dir, plan);
  if (Status s = save_plan(dir, plan); !s) return s.error();
  Submission out;
  out.already_done = plan.points.size() - pending.size();
  if (pending.empty()) return out;
  SlurmOptions so;
  so.driftlab = o.driftlab;
  so.point_flag = o.point_flag;
  so.job_name = "driftlab-" + plan.spec.name;
  for (char& c : so.job_name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  }
  so.max_parallel = o.max_parallel;
  so.requeue = o.requeue;
  so.slurm_options = o.slurm_options;
  so.sbatch = o.sbatch;
  auto r = make_slurm_executor(so)->execute(dir, pending);
  if (!r) return r.error();
  out.job_id = r->job_id;
  out.submitted = pending.size();
  return out;
}

extern const char kSweepPageScript[];  // sweep_page.py, generated into sweep_page_script.cc

Result<std::string> collect(const std::string& dir, const Plan& plan, bool plots) {
  auto json_path = write_tables(dir, plan);
  if (!json_path) return json_path.error();
  if (!plots) return std::string();
  if (Status s = run_plot_script(kSweepPageScript, "sweep_page.py", dir, {*json_path, dir}); !s) {
    return Error{"collect " + dir + ": " + s.message(), s.code()};
  }
  return (fs::path(dir) / "index.html").string();
}

nlohmann::json to_json(const LocalRun& run, const std::string& dir, const Plan& plan, const std::string& page) {
  const ExecutionSummary& r = run.summary;
  nlohmann::json j = {{"dir", dir},
                      {"points", plan.points.size()},
                      {"already_done", run.already_done},
                      {"done", r.done},
                      {"failed", r.failed},
                      {"not_started", r.not_started},
                      {"interrupted", r.interrupted},
                      {"wall_s", run.wall_s},
                      {"jobs", run.jobs},
                      {"table", (fs::path(dir) / "results.csv").string()}};
  if (!page.empty()) j["page"] = page;
  return j;
}

std::string local_run_text(const LocalRun& run, const std::string& dir, const std::optional<std::string>& page) {
  const ExecutionSummary& r = run.summary;
  std::string out;
  appendf(out, "%s %zu points in %.1f s (%zu already done): %zu done, %zu failed%s\n",
          r.interrupted ? "stopped after" : "ran", r.done + r.failed, run.wall_s, run.already_done, r.done, r.failed,
          r.interrupted ? "; finished points are kept, run the same command again to resume" : "");
  if (page) appendf(out, "table: %s/results.csv%s%s\n", dir.c_str(), page->empty() ? "" : ", page: ", page->c_str());
  return out;
}

std::string submission_text(const Submission& s, const std::string& dir, const Plan& plan) {
  std::string out;
  if (s.job_id.empty()) {
    appendf(out, "all %zu points of %s are done; nothing submitted\n", plan.points.size(), dir.c_str());
  } else {
    appendf(out,
            "submitted job %s: %zu points as a job array (%zu already done); follow with: driftlab sweep status %s\n",
            s.job_id.c_str(), s.submitted, s.already_done, dir.c_str());
  }
  return out;
}

}  // namespace driftlab::batch
