#include "analyzers/report_data.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>

#include "analyzers/diagnosis_json.h"
#include "analyzers/timing.h"
#include "analyzers/trajectory.h"
#include "core/time.h"

namespace driftlab::analyzers {
namespace {

namespace fs = std::filesystem;

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

/// A SLAM's loop tests drawn on its own trajectory: the pose channel of the same log that has the most of the
/// tests' keyframe stamps, and of those the one that began last (the whole trajectory as last optimised, published
/// at the end: the keyframes where the map has them; an estimator's poses at the same stamps come earlier), its
/// path (at most 5,000 points), and each test as a segment from the current keyframe to the old one, with its
/// outcome. Null when no pose channel has them.
nlohmann::json loops_json(const LogSeries& l, const LoopSeries& loops) {
  const auto at = [](const Trajectory& t, int64_t utime) -> std::optional<size_t> {
    const double s = Time::from_us(utime).seconds();
    const auto it = std::lower_bound(t.stamps.begin(), t.stamps.end(), s);
    if (it == t.stamps.end() || *it != s) return std::nullopt;
    return static_cast<size_t>(it - t.stamps.begin());
  };
  const auto began = [&](const std::string& name) {
    for (const auto& s : l.streams) {
      if (s.channel == name && !s.arrival.empty()) return s.arrival.front();
    }
    return 0.0;
  };
  const Trajectory* best = nullptr;
  std::string channel;
  size_t most = 0;
  for (const auto& [name, t] : l.poses) {
    if (!std::is_sorted(t.stamps.begin(), t.stamps.end())) continue;
    size_t found = 0;
    for (size_t i = 0; i < loops.utime.size(); ++i) found += at(t, loops.utime[i]) && at(t, loops.old_utime[i]);
    if (found > most || (found == most && found > 0 && began(name) > began(channel))) {
      most = found, best = &t, channel = name;
    }
  }
  if (best == nullptr) return nullptr;
  nlohmann::json path_x = nlohmann::json::array(), path_y = nlohmann::json::array();
  const size_t every = std::max<size_t>(1, best->size() / 5000);
  for (size_t i = 0; i < best->size(); i += every) {
    path_x.push_back(r6(best->positions[i].x()));
    path_y.push_back(r6(best->positions[i].y()));
  }
  nlohmann::json tests = nlohmann::json::array();
  std::map<std::string, int64_t> counts;
  for (size_t i = 0; i < loops.utime.size(); ++i) {
    ++counts[loops.outcome[i]];
    const auto a = at(*best, loops.utime[i]), b = at(*best, loops.old_utime[i]);
    if (!a || !b) continue;
    const auto &p = best->positions[*a], &q = best->positions[*b];
    tests.push_back({{"outcome", loops.outcome[i]}, {"x", {r6(p.x()), r6(q.x())}}, {"y", {r6(p.y()), r6(q.y())}}});
  }
  return {{"label", label_of(l.log, loops.channel)},
          {"trajectory", label_of(l.log, channel)},
          {"path_x", path_x},
          {"path_y", path_y},
          {"counts", counts},
          {"tests", tests}};
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
  return nlohmann::json{{"label", label},
                        {"alignment", "posyaw"},
                        {"t", t},
                        {"x", x},
                        {"y", y},
                        {"error", err},
                        {"ate_rmse", e.trans.rmse},
                        {"ate_max", e.trans.max},
                        {"matched", m.est.size()}};
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

std::string map_file(const LogSeries& log, const MapImage& map) {
  return "map-" + fs::path(log.log).stem().string() + "-" + map.channel + ".png";
}

Result<nlohmann::json> report_data(const ReportInputs& in) {
  const std::vector<LogSeries>& logs = in.logs;
  const std::vector<std::string>& names = in.names;
  const LogSeries& first = logs.front();
  const double origin_s = Time::from_us(first.start_utime).seconds();
  const nlohmann::json& diagnosis = in.diagnosis;
  nlohmann::json data;
  data["title"] = in.title.empty() ? "driftlab report: " + fs::path(names[0]).filename().string() : in.title;
  data["logs"] = nlohmann::json::array();
  for (size_t k = 0; k < logs.size(); ++k) {
    const LogSeries& l = logs[k];
    data["logs"].push_back({{"path", names[k]},  // as given; the conversion read is l.log
                            {"start_utime", l.start_utime},
                            {"duration_s", seconds_between(l.start_utime, l.end_utime)},
                            {"problems", l.problems}});
  }
  data["diagnosis"] = diagnosis;
  data["evals"] = in.evals;

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
    auto summary = analyzers::summarize(diagnosis);
    if (!summary) return summary.error();
    data["summary"] = to_json(*summary);
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("not the JSON of driftlab diagnose --json (") + e.what() + ")"};
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
    if (auto it = logs[k].poses.find(in.gt_channel); it != logs[k].poses.end() && it->second.size() > 0) {
      gt = &it->second;
      gt_log = k;
      data["reference"] = path_json(label_of(names[k], in.gt_channel), *gt, origin_s);
      break;
    }
  }
  // Each log's reference: its own when it flew again (its truth differs from the first's), else the first's.
  std::vector<const Trajectory*> reference_of(logs.size(), gt);
  data["other_references"] = nlohmann::json::array();
  for (size_t k = gt_log + 1; gt != nullptr && k < logs.size(); ++k) {
    auto it = logs[k].poses.find(in.gt_channel);
    if (it == logs[k].poses.end() || it->second.size() < 2 || same_poses(*gt, it->second)) continue;
    reference_of[k] = &it->second;
    data["other_references"].push_back(path_json(label_of(names[k], in.gt_channel), it->second, origin_s));
  }
  // The body the reference tracks (its child frame): a pose channel of another body (an arm's end effector beside
  // its base's ground truth) is no estimate of it; drawn apart, in its own frame, never overlaid.
  const std::string gt_body = gt == nullptr ? std::string() : [&] {
    auto b = logs[gt_log].pose_bodies.find(in.gt_channel);
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
      if (channel == in.gt_channel || t.size() < 2) continue;
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
        if (reference_of[k] != gt) (*e)["reference"] = label_of(names[k], in.gt_channel);
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

  data["loops"] = nlohmann::json::array();
  for (const auto& l : logs) {
    for (const auto& loops : l.loops) {
      if (auto j = loops_json(l, loops); !j.is_null()) data["loops"].push_back(std::move(j));
    }
  }

  data["maps"] = nlohmann::json::array();
  for (const auto& l : logs) {
    for (const auto& m : l.maps) {
      data["maps"].push_back(
          {{"label", label_of(l.log, m.channel)}, {"file", map_file(l, m)}, {"width", m.width}, {"height", m.height}});
    }
  }
  return data;
}

}  // namespace driftlab::analyzers
