#include "batch/store.h"
#include "core/text_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace driftlab::batch {
namespace {

namespace fs = std::filesystem;

std::string csv_field(const nlohmann::json& v) {
  std::string s;
  if (v.is_null()) return "";
  if (v.is_string()) {
    s = v.get<std::string>();
  } else if (v.is_number_float()) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.9g", v.get<double>());
    s = buf;
  } else {
    s = v.dump();
  }
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

std::string host_name() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof(buf) - 1) != 0) return "?";
  return buf;
}

Result<nlohmann::json> read_json_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{path + ": cannot open"};
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    return Error{path + ": not JSON (byte " + std::to_string(e.byte) + ")"};
  }
}

std::string plan_path(const std::string& dir) { return (fs::path(dir) / "plan.json").string(); }
std::string point_dir(const std::string& dir, const std::string& id) { return (fs::path(dir) / "points" / id).string(); }
std::string result_path(const std::string& dir, const std::string& id) {
  return (fs::path(point_dir(dir, id)) / "result.json").string();
}

Status save_plan(const std::string& dir, const Plan& plan) {
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "points", ec);
  if (ec) return Error{dir + ": cannot create the sweep folder: " + ec.message(), ErrorCode::kCannotWrite};
  return write_file_atomically(plan_path(dir), to_json(plan).dump(1) + "\n", kSynced);
}

Result<Plan> load_plan(const std::string& dir) {
  const std::string p = plan_path(dir);
  if (!fs::exists(p)) return Error{dir + ": not a sweep or batch folder (no plan.json)"};
  auto j = read_json_file(p);
  if (!j) return j.error();
  return plan_from_json(*j, p);
}

const char* state_name(PointState s) {
  switch (s) {
    case PointState::kPending: return "pending";
    case PointState::kRunning: return "running";
    case PointState::kDone: return "done";
    case PointState::kFailed: return "failed";
  }
  return "?";
}

bool is_done(const std::string& dir, const std::string& id) { return fs::exists(result_path(dir, id)); }

PointStatus point_status(const std::string& dir, const std::string& id) {
  PointStatus st;
  st.id = id;
  const fs::path d = point_dir(dir, id);
  {
    std::ifstream a(d / "attempts");
    a >> st.attempts;
  }
  for (auto [file, state] : {std::pair{"result.json", PointState::kDone}, std::pair{"running.json", PointState::kRunning},
                             std::pair{"failed.json", PointState::kFailed}}) {
    if (!fs::exists(d / file)) continue;
    auto j = read_json_file((d / file).string());
    st.state = state;
    st.record = j ? *j : nlohmann::json();
    // An attempt on this host whose process is gone was killed outright (it leaves no failed.json).
    if (state == PointState::kRunning && st.record.is_object() && st.record.value("host", "") == host_name() &&
        ::kill(st.record.value("pid", 0), 0) != 0 && errno == ESRCH) {
      st.state = PointState::kFailed;
      st.record["error"] = "killed: process " + std::to_string(st.record.value("pid", 0)) + " is gone";
    }
    return st;
  }
  return st;
}

int count_attempt(const std::string& dir, const std::string& id) {
  const fs::path f = fs::path(point_dir(dir, id)) / "attempts";
  int n = 0;
  {
    std::ifstream a(f);
    a >> n;
  }
  ++n;
  (void)write_file_atomically(f.string(), std::to_string(n) + "\n", kSynced);
  return n;
}

Table merge_results(const std::string& dir, const Plan& plan) {
  Table t;
  t.columns = {"id", "status", "attempts"};
  if (!plan.spec.logs.empty()) t.columns.push_back("log");  // batches, and sweeps over logs
  for (const auto& p : plan.spec.vary) t.columns.push_back(p.key);
  std::set<std::string> metrics, seconds;
  for (const auto& pt : plan.points) {
    const PointStatus st = point_status(dir, pt.id);
    nlohmann::json row = {{"id", pt.id}, {"status", state_name(st.state)}, {"attempts", st.attempts}};
    for (const auto& [k, v] : pt.params) row[k] = v.json();
    if (st.state == PointState::kDone && st.record.is_object()) {
      const nlohmann::json metric_values = st.record.value("metrics", nlohmann::json::object());
      const nlohmann::json stage_seconds = st.record.value("seconds", nlohmann::json::object());
      for (const auto& [k, v] : metric_values.items()) {
        row[k] = v;
        metrics.insert(k);
      }
      for (const auto& [k, v] : stage_seconds.items()) {
        row["seconds." + k] = v;
        seconds.insert("seconds." + k);
      }
    } else if (st.state == PointState::kFailed && st.record.is_object()) {
      row["error"] = st.record.value("error", "");
      metrics.insert("error");
    }
    t.rows.push_back(std::move(row));
  }
  t.columns.insert(t.columns.end(), metrics.begin(), metrics.end());
  t.columns.insert(t.columns.end(), seconds.begin(), seconds.end());
  return t;
}

std::string table_csv(const Table& t) {
  std::ostringstream out;
  for (size_t i = 0; i < t.columns.size(); ++i) out << (i ? "," : "") << csv_field(t.columns[i]);
  out << "\n";
  for (const auto& row : t.rows) {
    for (size_t i = 0; i < t.columns.size(); ++i) {
      out << (i ? "," : "") << (row.contains(t.columns[i]) ? csv_field(row[t.columns[i]]) : "");
    }
    out << "\n";
  }
  return out.str();
}

nlohmann::json rank_batch(const Table& t) {
  std::vector<nlohmann::json> rows(t.rows.begin(), t.rows.end());
  auto key = [](const nlohmann::json& r) {
    const double ate = r.contains("ate_rmse") && r["ate_rmse"].is_number() ? r["ate_rmse"].get<double>() : 0;
    return std::tuple(r.value("status", "") == "done" ? 1 : 0, r.value("fault_streams", 0), r.value("warn_streams", 0),
                      r.value("drops", int64_t{0}), ate);
  };
  std::stable_sort(rows.begin(), rows.end(), [&](const auto& a, const auto& b) { return key(a) > key(b); });
  return rows;
}

}  // namespace driftlab::batch
