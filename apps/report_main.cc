// driftlab report LOG... --out DIR: one self-contained HTML page (and a PNG of each plot) that shows what the
// logs say: trajectories against ground truth, error over time with drops, gaps and latency spikes on the same
// axis, latency histograms, inter-arrival times, skew correlation curves, the SLAM map, and an arm's commanded
// against measured joint motion with the delay between them.
//
// This file gathers the data (analyzers/log_series.h, the timing diagnosis, trajectory error) into DIR/report.json;
// matplotlib draws it (analyzers/report_page.py, compiled into the program), since a maintained plotting library
// draws better plots than we would by hand.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>

#include "analyzers/diagnosis_json.h"
#include "analyzers/flight_log.h"
#include "analyzers/flight_log_pair.h"
#include "analyzers/log_series.h"
#include "analyzers/timing.h"
#include "analyzers/trajectory.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/log_input.h"
#include "apps/report.h"
#include "core/same_file.h"
#include "core/text_file.h"
#include "core/time.h"

namespace driftlab::apps {

extern const char kReportPageScript[];  // analyzers/report_page.py, generated into report_page_script.cc

namespace {

namespace fs = std::filesystem;
using namespace analyzers;

/// Rounds to the microsecond (seconds) or micrometre (metres): the JSON stays a third of the size.
double r6(double v) { return std::round(v * 1e6) / 1e6; }

nlohmann::json rounded(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(r6(x));
  return a;
}

std::string label_of(const std::string& log, const std::string& channel) {
  return fs::path(log).filename().string() + ":" + channel;
}

Result<nlohmann::json> read_json(const std::string& path, const char* option) {
  auto text = read_text_file(path, "JSON file");
  if (!text) return Error{std::string(option) + " " + text.error().message};
  try {
    return nlohmann::json::parse(*text);
  } catch (const nlohmann::json::parse_error& e) {
    return Error{std::string(option) + " " + path + ": not JSON (byte " + std::to_string(e.byte) + ")"};
  }
}

/// A stream's plot data: arrivals, latency, its latency spikes (above the diagnosed median by more than 10 ms and
/// three times the p99's distance from it) and its drop gaps, from the diagnosis of its channel.
/// The latency is the diagnosis' own: through the mapping of the stream's clock when it is of another epoch
/// (simulation time: against the fastest stream on it, never arrival minus a stamp of another clock), and none
/// where the diagnosis has none (static transforms, stamps never set).
nlohmann::json stream_json(const StreamSeries& s, const nlohmann::json& diagnosed, const nlohmann::json& domains,
                           double origin_s) {
  std::vector<double> latency;
  const auto& diagnosed_latency = diagnosed.at("latency_s");
  if (diagnosed_latency.is_object()) latency = s.latency;
  const auto& domain = diagnosed.value("domain", nlohmann::json());
  const bool mapped = domain.is_number_integer() && domain.get<int64_t>() >= 0 &&
                      domain.get<size_t>() < domains.size() && domains[domain.get<size_t>()].value("mapped", false);
  if (mapped) {
    const auto knots = domains[domain.get<size_t>()].value("mapping", std::vector<std::array<double, 2>>{});
    for (size_t i = 0; i < latency.size(); ++i) {
      const double stamp = origin_s + s.arrival[i] - latency[i];
      latency[i] -= analyzers::mapped_offset_s(knots, stamp);
    }
  }
  nlohmann::json j = {{"channel", s.channel},
                      {"type", s.type},
                      {"has_header", s.has_header},
                      {"arrival", rounded(s.arrival)},
                      {"latency", rounded(latency)},
                      {"mapped_clock", mapped},
                      {"verdict", diagnosed.at("verdict")},
                      {"expected_period_s", diagnosed.at("expected_period_s")}};
  nlohmann::json spikes = nlohmann::json::array();
  if (!latency.empty()) {
    const double p50 = diagnosed_latency.at("p50"), p99 = diagnosed_latency.at("p99");
    const double threshold = p50 + std::max(0.010, 3 * (p99 - p50));
    for (size_t i = 0; i < latency.size(); ++i) {
      if (latency[i] > threshold) spikes.push_back({r6(s.arrival[i]), r6(latency[i])});
    }
    j["spike_threshold"] = r6(threshold);
  }
  j["spikes"] = spikes;
  nlohmann::json gaps = nlohmann::json::array();
  for (const auto& g : diagnosed.at("drops").at("gaps")) {
    gaps.push_back({r6(g.at("start_utime").get<double>() * 1e-6 - origin_s),
                    r6(g.at("end_utime").get<double>() * 1e-6 - origin_s), g.at("missing")});
  }
  j["gaps"] = gaps;
  return j;
}

/// An estimate aligned onto the reference (posyaw: it may start anywhere in the map frame) and its error over time.
std::optional<nlohmann::json> estimate_json(const std::string& label, const Trajectory& gt, const Trajectory& est,
                                            double origin_s) {
  Matched m = match_interpolated(gt, est, 0.1, 0);
  if (m.ref.size() < 2) return std::nullopt;
  const Alignment a = align(m, AlignmentType::kPosYaw);
  m.est = apply(a, std::move(m.est));
  const ApeResult e = ape(m);
  nlohmann::json t = nlohmann::json::array(), x = nlohmann::json::array(), y = nlohmann::json::array();
  nlohmann::json err = nlohmann::json::array();
  for (size_t i = 0; i < m.est.size(); ++i) {
    t.push_back(r6(m.est.stamps[i] - origin_s));
    x.push_back(r6(m.est.positions[i].x()));
    y.push_back(r6(m.est.positions[i].y()));
    err.push_back(r6(e.trans_errors[i]));
  }
  return nlohmann::json{{"label", label}, {"alignment", "posyaw"}, {"t", t}, {"x", x}, {"y", y}, {"error", err},
                        {"ate_rmse", e.trans.rmse}, {"ate_max", e.trans.max}, {"matched", m.est.size()}};
}

nlohmann::json path_json(const std::string& label, const Trajectory& t, double origin_s) {
  nlohmann::json ts = nlohmann::json::array(), x = nlohmann::json::array(), y = nlohmann::json::array();
  for (size_t i = 0; i < t.size(); ++i) {
    ts.push_back(r6(t.stamps[i] - origin_s));
    x.push_back(r6(t.positions[i].x()));
    y.push_back(r6(t.positions[i].y()));
  }
  return {{"label", label}, {"t", ts}, {"x", x}, {"y", y}};
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
    auto path = event_log_for(given);  // another tool's recording: its cached conversion
    if (!path) return path.error();
    auto s = read_log_series(*path);
    if (!s) return s.error();
    if (s->streams.empty()) return Error{name + ": no events"};
    logs.push_back(std::move(*s));
  }
  const LogSeries& first = logs.front();
  const double origin_s = Time::from_us(first.start_utime).seconds();

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

  nlohmann::json data;
  data["title"] = o.title.empty() ? "driftlab report: " + fs::path(names[0]).filename().string() : o.title;
  data["logs"] = nlohmann::json::array();
  for (size_t k = 0; k < logs.size(); ++k) {
    const LogSeries& l = logs[k];
    data["logs"].push_back({{"path", names[k]},  // as given; the conversion read is l.log
                            {"start_utime", l.start_utime},
                            {"duration_s", seconds_between(l.start_utime, l.end_utime)},
                            {"problems", l.problems}});
  }
  data["diagnosis"] = diagnosis;
  data["evals"] = evals;

  // Streams of the first log (the recording); later logs are replays whose inputs repeat it.
  std::map<std::string, nlohmann::json> diagnosed;
  data["streams"] = nlohmann::json::array();
  try {
    for (const auto& c : diagnosis.at("channels")) diagnosed[c.at("name").get<std::string>()] = c;
    for (const auto& s : first.streams) {
      if (!diagnosed.count(s.channel)) continue;  // what the diagnosis leaves out (fault manifests, statistics)
      data["streams"].push_back(
          stream_json(s, diagnosed[s.channel], diagnosis.value("clock_domains", nlohmann::json::array()), origin_s));
    }
    data["summary"] = analyzers::diagnosis_summary(diagnosis);
  } catch (const nlohmann::json::exception& e) {
    return Error{"--diagnosis " + o.diagnosis + ": not the JSON of driftlab diagnose --json (" + e.what() + ")"};
  }

  // Trajectories: the reference from the first log that has it; estimates: every pose channel of the first log
  // and those of later logs that the first does not have (the replays' outputs), or has but holds other poses of:
  // a run flown again (a closed-loop replay) is drawn with the other flights, its estimate against its own
  // reference, drawn too. A pose channel a later log repeats as it was is a replayed input, drawn once.
  auto same_poses = [](const Trajectory& a, const Trajectory& b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i) {
      if (std::abs(a.stamps[i] - b.stamps[i]) > 1e-6 || (a.positions[i] - b.positions[i]).norm() > 1e-6) return false;
    }
    return true;
  };
  const Trajectory* gt = nullptr;
  size_t gt_log = 0;
  for (size_t k = 0; k < logs.size(); ++k) {
    if (auto it = logs[k].poses.find(o.gt_channel); it != logs[k].poses.end() && it->second.size() > 0) {
      gt = &it->second;
      gt_log = k;
      data["reference"] = path_json(label_of(names[k], o.gt_channel), *gt, origin_s);
      break;
    }
  }
  // Each log's reference: its own when it flew again (its truth differs from the first's), else the first's.
  std::vector<const Trajectory*> reference_of(logs.size(), gt);
  data["other_references"] = nlohmann::json::array();
  for (size_t k = gt_log + 1; gt != nullptr && k < logs.size(); ++k) {
    auto it = logs[k].poses.find(o.gt_channel);
    if (it == logs[k].poses.end() || it->second.size() < 2 || same_poses(*gt, it->second)) continue;
    reference_of[k] = &it->second;
    data["other_references"].push_back(path_json(label_of(names[k], o.gt_channel), it->second, origin_s));
  }
  // The body the reference tracks (its child frame): a pose channel of another body (an arm's end effector beside
  // its base's ground truth) is no estimate of it; drawn apart, in its own frame, never overlaid.
  const std::string gt_body = gt == nullptr ? std::string() : [&] {
    auto b = logs[gt_log].pose_bodies.find(o.gt_channel);
    return b == logs[gt_log].pose_bodies.end() ? std::string() : b->second;
  }();
  auto body_of = [&](size_t k, const std::string& channel) {
    auto b = logs[k].pose_bodies.find(channel);
    return b == logs[k].pose_bodies.end() ? std::string() : b->second;
  };
  data["estimates"] = nlohmann::json::array();
  data["apart"] = nlohmann::json::array();
  data["unmatched"] = nlohmann::json::array();
  // Without a reference, poses in different frames (AMCL's in 'map', odometry in 'odom') are drawn aligned in
  // position and yaw onto the longest of them, as evo_traj --ref does, never overlaid as they are; one that cannot
  // be aligned is left out and named.
  const Trajectory* frame = nullptr;
  std::string frame_label, frame_body;
  if (gt == nullptr) {
    for (const auto& [channel, t] : first.poses) {
      if (frame == nullptr || t.size() > frame->size()) {
        frame = &t;
        frame_label = channel;
        frame_body = body_of(0, channel);
      }
    }
  }
  const std::string& body = gt != nullptr ? gt_body : frame_body;
  for (size_t k = 0; k < logs.size(); ++k) {
    for (const auto& [channel, t] : logs[k].poses) {
      if (channel == o.gt_channel || t.size() < 2) continue;
      if (k > 0) {
        if (auto it = first.poses.find(channel); it != first.poses.end() && same_poses(it->second, t)) continue;
      }
      const std::string label = label_of(names[k], channel);
      if (const std::string own = body_of(k, channel); !own.empty() && !body.empty() && own != body) {
        auto drawn = path_json(label, t, origin_s);
        drawn["body"] = own;
        drawn["not_of"] = body;
        data["apart"].push_back(std::move(drawn));
        continue;
      }
      if (gt == nullptr && (frame == &t || frame == nullptr)) {
        data["estimates"].push_back(path_json(label, t, origin_s));
      } else if (gt == nullptr) {
        Matched m = match_interpolated(*frame, t, 0.1, 0);
        const Alignment a = m.ref.size() >= 2 ? align(m, AlignmentType::kPosYaw)
                                              : Alignment{.problem =
                                                              "no poses "
                                                              "at its times"};
        if (!a.problem.empty()) {
          data["unmatched"].push_back(label + " (not aligned with " + label_of(names[0], frame_label) + ": " +
                                      a.problem + ")");
          continue;
        }
        auto drawn = path_json(label + " (aligned to " + frame_label + ")", apply(a, t), origin_s);
        drawn["aligned_to"] = frame_label;
        data["estimates"].push_back(std::move(drawn));
      } else if (auto e = estimate_json(label, *reference_of[k], t, origin_s)) {
        if (reference_of[k] != gt) (*e)["reference"] = label_of(names[k], o.gt_channel);
        data["estimates"].push_back(std::move(*e));
      } else {
        data["unmatched"].push_back(label + " (no time overlap with the reference)");
      }
    }
  }

  // Arms: commanded against measured joint motion, with the delay diagnose measured between them.
  data["arms"] = nlohmann::json::array();
  for (const auto& a : first.arms) {
    nlohmann::json loop;
    for (const auto& l : diagnosis.value("command_loops", nlohmann::json::array())) {
      if (l.is_object() && l.value("command", "") == a.command_channel) loop = l;
    }
    nlohmann::json commanded = nlohmann::json::array(), measured = nlohmann::json::array();
    for (size_t j = 0; j < a.joints.size(); ++j) {
      commanded.push_back(rounded(a.commanded[j]));
      measured.push_back(rounded(a.measured[j]));
    }
    data["arms"].push_back(
        {{"command_channel", a.command_channel},
         {"state_channel", a.state_channel},
         {"joints", a.joints},
         {"t", rounded(a.t)},
         {"commanded", commanded},
         {"measured", measured},
         {"delay_s", loop.is_object() ? loop.value("delay_s", nlohmann::json()) : nlohmann::json()},
         {"confidence", loop.is_object() ? loop.value("confidence", 0.0) : 0.0},
         {"curve", loop.is_object() ? loop.value("curve", nlohmann::json::array()) : nlohmann::json::array()}});
  }

  // Estimators: what each log's estimator did with its inputs, fused and rejected by reason, over time.
  data["estimators"] = nlohmann::json::array();
  for (const auto& l : logs) {
    for (const auto& e : l.estimators) {
      nlohmann::json inputs = nlohmann::json::array();
      for (size_t i = 0; i < e.inputs.size(); ++i) {
        inputs.push_back({{"name", e.inputs[i]},
                          {"fused", e.fused[i]},
                          {"stale", e.stale[i]},
                          {"future", e.future[i]},
                          {"late", e.late[i]},
                          {"outliers", e.outliers[i]}});
      }
      data["estimators"].push_back({{"label", label_of(l.log, e.channel)}, {"t", rounded(e.t)}, {"inputs", inputs}});
    }
  }

  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Error{o.out + ": cannot create the report folder: " + ec.message()};
  data["maps"] = nlohmann::json::array();
  for (const auto& l : logs) {
    for (const auto& m : l.maps) {
      const std::string file = "map-" + fs::path(l.log).stem().string() + "-" + m.channel + ".png";
      const std::string_view png(reinterpret_cast<const char*>(m.png.data()), m.png.size());
      if (auto st = write_atomically((fs::path(o.out) / file).string(), png); !st) return Error{st.message()};
      data["maps"].push_back({{"label", label_of(l.log, m.channel)}, {"file", file}, {"width", m.width},
                              {"height", m.height}});
    }
  }

  stage("drawing the plots");
  const std::string json_path = (fs::path(o.out) / "report.json").string();
  if (auto st = write_atomically(json_path, data.dump() + "\n"); !st) return Error{st.message()};
  if (Status st = run_plot_script(kReportPageScript, "report_page.py", o.out, {json_path, o.out}); !st) {
    // A write error names the folder (exit 1, as every write error); anything else is the plotting's.
    return Error{st.message().starts_with(o.out + ":") ? st.message() : "report: " + st.message()};
  }
  return (fs::path(o.out) / "index.html").string();
}

void add_report_command(CLI::App& app, int* exit_code) {
  auto o = std::make_shared<ReportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Write one self-contained HTML page with plots (and a PNG of each) of what the logs say.");
  cmd->footer(
      "The first LOG is the recording (a simulator or recorder log); later logs are replays of it, whose new pose\n"
      "channels are shown as estimates. A PX4 flight log (.ulg) given with a bag of the same flight is one\n"
      "recording, the flight log put on the bag's clock as `driftlab diagnose BAG FLIGHT.ulg` does. Plots:\n"
      "trajectories in the plane (estimates aligned in position and yaw); error over time with drops, gaps and\n"
      "latency spikes on the same axis; latency over time and histograms; inter-arrival times; skew correlation\n"
      "curves; SLAM maps; an arm's commanded and measured joint motion with the delay diagnose measures between\n"
      "them; a PX4 flight log's timeline (the logger's dropouts, sensor gaps, the estimator's rejections and\n"
      "timeouts on one axis). The time plots zoom in the page (dygraphs, from libjs-dygraphs, inlined: it opens\n"
      "offline; without it the page keeps the PNGs). Without --diagnosis the first log is diagnosed. Needs python3\n"
      "with matplotlib. DIR gets index.html, a PNG per plot and report.json (the data plotted).");
  cmd->add_option("logs", o->logs, "Logs: the recording first, then replays of it")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--out", o->out, "Folder to write the report into")->required();
  cmd->add_option("--diagnosis", o->diagnosis, "Diagnosis of the first log (driftlab diagnose --json)");
  cmd->add_option("--eval", o->evals, "Trajectory or arm evaluation to tabulate (driftlab eval --json; repeatable)");
  cmd->add_option("--gt", o->gt_channel, "Ground-truth channel")->capture_default_str();
  cmd->add_option("--title", o->title, "Page title (default: from the first log)");
  cmd->callback([o, exit_code] {
    std::vector<std::string> inputs = o->logs;
    inputs.push_back(o->diagnosis);
    inputs.insert(inputs.end(), o->evals.begin(), o->evals.end());
    if (Status s = refuse_same_file(o->out, inputs, "-o", OutputKind::kFolder); !s) {
      *exit_code = fail(s.message());
      return;
    }
    StageLine line("report");
    ReportOptions options = *o;
    options.on_stage = [&line](const std::string& what) { line.set("report: " + what); };
    auto page = make_report(options);
    line.finish();
    if (!page) {
      *exit_code =
          fail(page.error().message,
               exit_code_for_input(page.error()) == kExitFailure ? kExitFailure : exit_code_for(page.error(), o->out));
      return;
    }
    std::printf("%s\n", page->c_str());
    *exit_code = kExitOk;
  });
}

}  // namespace driftlab::apps
