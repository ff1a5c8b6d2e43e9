#include "reporting/report.h"

#include <nlohmann/json.hpp>

#include <filesystem>

#include "analyzers/diagnosis_json.h"
#include "analyzers/flight_log.h"
#include "analyzers/flight_log_pair.h"
#include "analyzers/log_series.h"
#include "analyzers/report_data.h"
#include "core/process.h"
#include "core/text_file.h"
#include "recordings/log_input.h"

namespace driftlab::report {

extern const char kReportPageScript[];  // analyzers/report_page.py, generated into report_page_script.cc

namespace {

namespace fs = std::filesystem;
using namespace analyzers;

Result<nlohmann::json> read_json(const std::string& path, const char* option) {
  auto text = read_text_file(path, "JSON file");
  if (!text) return Error{std::string(option) + " " + text.error().message};
  try {
    return nlohmann::json::parse(*text);
  } catch (const nlohmann::json::parse_error& e) {
    return Error{std::string(option) + " " + path + ": not JSON (byte " + std::to_string(e.byte) + ")"};
  }
}

}  // namespace

Result<std::string> make_report(const ReportOptions& o) {
  if (o.logs.empty()) return Error{"report: no log given"};
  const auto stage = [&o](const std::string& what) {
    if (o.on_stage) o.on_stage(what);
  };
  std::vector<LogSeries> logs;
  std::vector<std::string> names;  // as given: a bag's own name, not its conversion's
  // A flight log beside a bag of the same flight is one recording, on the bag's clock (analyzers/flight_log_pair.h).
  std::vector<std::vector<std::string>> recordings;
  if (analyzers::flight_log_pair(o.logs)) {
    recordings.push_back(o.logs);
  } else {
    for (const auto& given : o.logs) recordings.push_back({given});
  }
  for (const auto& given : recordings) {
    std::string name = given[0];
    for (size_t i = 1; i < given.size(); ++i) name += " + " + given[i];
    names.push_back(name);
    stage("reading " + name);
    auto path = recordings::event_log_for(given);  // another tool's recording: its cached conversion
    if (!path) return path.error();
    auto s = read_log_series(*path);
    if (!s) return s.error();
    if (s->streams.empty()) return Error{name + ": no events"};
    logs.push_back(std::move(*s));
  }
  const LogSeries& first = logs.front();

  nlohmann::json diagnosis;
  if (!o.diagnosis.empty()) {
    auto d = read_json(o.diagnosis, "--diagnosis");
    if (!d) return d.error();
    diagnosis = std::move(*d);
    if (!diagnosis.is_object() || !diagnosis.contains("channels")) {
      return Error{"--diagnosis " + o.diagnosis + ": not the JSON of driftlab diagnose --json (no \"channels\")"};
    }
    // A PX4 flight log: its flight-log diagnosis (dropouts, sensor gaps, the estimator's rejections) for the
    // timeline, unless the diagnosis given already holds it.
    if (!diagnosis.contains("flight_log")) {
      auto f = analyzers::diagnose_flight_log(first.log);
      if (!f) return f.error();
      if (f->present) diagnosis["flight_log"] = analyzers::flight_log_json(*f);
    }
  } else {
    stage("diagnosing " + names.front());
    auto run = analyzers::run_diagnosis(first.log, {});  // as diagnose --json: with a flight log's own diagnosis
    if (!run) return run.error();
    diagnosis = analyzers::diagnose_json(*run);
  }
  nlohmann::json evals = nlohmann::json::array();
  for (const auto& path : o.evals) {
    auto e = read_json(path, "--eval");
    if (!e) return e.error();
    if (!e->is_object() || (!e->contains("ate") && !e->contains("arm"))) {
      return Error{"--eval " + path + ": not the JSON of driftlab eval --json (no \"ate\" or \"arm\")"};
    }
    evals.push_back({{"file", fs::path(path).filename().string()}, {"result", std::move(*e)}});
  }

  const analyzers::ReportInputs inputs{.logs = std::move(logs),
                                       .names = std::move(names),
                                       .diagnosis = std::move(diagnosis),
                                       .evals = std::move(evals),
                                       .gt_channel = o.gt_channel,
                                       .title = o.title};
  auto data = analyzers::report_data(inputs);
  if (!data) return Error{"--diagnosis " + o.diagnosis + ": " + data.error().message};
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Error{o.out + ": cannot create the report folder: " + ec.message(), ErrorCode::kCannotWrite};
  for (const auto& l : inputs.logs) {
    for (const auto& m : l.maps) {
      const std::string_view png(reinterpret_cast<const char*>(m.png.data()), m.png.size());
      if (auto st = write_file_atomically((fs::path(o.out) / analyzers::map_file(l, m)).string(), png); !st) {
        return st.error();
      }
    }
  }

  stage("drawing the plots");
  const std::string json_path = (fs::path(o.out) / "report.json").string();
  if (auto st = write_file_atomically(json_path, data->dump() + "\n"); !st) return st.error();
  if (Status st = run_plot_script(kReportPageScript, "report_page.py", o.out, {json_path, o.out}); !st) {
    // A write error names the folder (exit 1, as every write error); anything else is the plotting's.
    return st.code() == ErrorCode::kCannotWrite ? st.error() : Error{"report: " + st.message()};
  }
  return (fs::path(o.out) / "index.html").string();
}

}  // namespace driftlab::report
