#include "analyzers/log_series.h"

#include <algorithm>

#include "analyzers/internal/joint_motion.h"
#include "analyzers/timing.h"
#include "analyzers/trajectory_io.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/time.h"
#include "driftlab/estimator_status_t.hpp"
#include "driftlab/image_t.hpp"
#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_t.hpp"
#include "driftlab/loop_closure_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

/// At most this many samples of an arm's joints are kept (a plot has no more pixels).
constexpr size_t kMaxArmSamples = 20'000;

std::vector<ArmSeries> arm_series(const std::map<std::string, internal::JointCommands>& commands,
                                  const std::map<std::string, internal::JointStates>& states, int64_t start_utime) {
  std::vector<ArmSeries> out;
  for (const auto& [channel, c] : commands) {
    const internal::JointStates* js = nullptr;
    ArmSeries a;
    for (const auto& [name, s] : states) {
      if (s.has_all(c.joints) && s.stamp.size() >= 2 && (js == nullptr || s.stamp.size() > js->stamp.size())) {
        js = &s;
        a.state_channel = name;
      }
    }
    if (js == nullptr || c.list.empty()) continue;
    a.command_channel = channel;
    a.joints = c.joints;
    a.commanded.resize(c.joints.size());
    a.measured.resize(c.joints.size());
    const internal::CommandedMotion motion(c);
    std::vector<size_t> columns;
    for (const auto& j : c.joints) columns.push_back(js->index.at(j));
    size_t in_span = 0;
    for (int64_t t : js->stamp) in_span += t >= motion.start() && t <= motion.end();
    const size_t every = in_span / kMaxArmSamples + 1;
    std::vector<double> q;
    size_t n = 0;
    for (size_t k = 0; k < js->stamp.size(); ++k) {
      const int64_t t = js->stamp[k];
      if (t < motion.start() || t > motion.end() || n++ % every != 0 || !motion.at(t, q)) continue;
      a.t.push_back(Time::from_us(t).seconds_since(Time::from_us(start_utime)));
      for (size_t j = 0; j < columns.size(); ++j) {
        a.commanded[j].push_back(q[j]);
        a.measured[j].push_back(js->q[k][columns[j]]);
      }
    }
    if (!a.t.empty()) out.push_back(std::move(a));
  }
  return out;
}

}  // namespace

Result<LogSeries> read_log_series(const std::string& log, const std::string& channels) {
  auto reader = LogReader::open(log, {.channels = channels});
  if (!reader) return reader.error();
  LogSeries out;
  out.log = log;
  std::map<std::string, size_t, std::less<>> index;  // channel -> streams[i]
  std::vector<std::vector<int64_t>> arrivals, stamps;
  std::vector<int64_t> ready_after;  // per stream, from its first message (a scan's sweep)
  const int64_t image_hash = driftlab::image_t::getHash();
  const int64_t status_hash = driftlab::estimator_status_t::getHash();
  const int64_t command_hash = driftlab::joint_trajectory_t::getHash();
  const int64_t joint_state_hash = driftlab::joint_state_t::getHash();
  const int64_t loop_hash = driftlab::loop_closure_t::getHash();
  std::map<std::string, internal::JointCommands> commands;
  std::map<std::string, internal::JointStates> joint_states;
  Event e;
  bool first = true;
  while (reader->next(e)) {
    if (first) out.start_utime = out.end_utime = e.utime;
    first = false;
    out.start_utime = std::min(out.start_utime, e.utime);
    out.end_utime = std::max(out.end_utime, e.utime);
    auto it = index.find(e.channel);
    if (it == index.end()) {
      StreamSeries s;
      s.channel = std::string(e.channel);
      const lcmtypes::TypeInfo* type = lcmtypes::find_type(logfmt::fingerprint(e.data));
      s.type = type != nullptr ? type->name : "";
      s.has_header = lcmtypes::has_header(e.data, e.utime);
      it = index.emplace(s.channel, out.streams.size()).first;
      out.streams.push_back(std::move(s));
      arrivals.emplace_back();
      stamps.emplace_back();
      ready_after.push_back(lcmtypes::ready_after_us(e.data));
    }
    const size_t k = it->second;
    StreamSeries& s = out.streams[k];
    arrivals[k].push_back(e.utime);
    if (s.has_header) {
      if (const auto stamp = lcmtypes::header_stamp(e.data, e.utime)) {
        stamps[k].push_back(*stamp);
      } else {
        s.has_header = false;  // a message without a header (too short, or a coincidence): the channel is untyped
      }
    }
    const int64_t fp = logfmt::fingerprint(e.data);
    if (fp == driftlab::pose_t::getHash() || fp == driftlab::odometry_t::getHash()) {
      append_pose(e.data, out.poses[s.channel]);
      if (!out.pose_bodies.count(s.channel)) {  // the body the first pose is of: what the channel tracks
        std::string body;
        if (fp == driftlab::pose_t::getHash()) {
          if (driftlab::pose_t m; lcmtypes::decode(e.data, m)) body = m.child_frame_id;
        } else if (driftlab::odometry_t m; lcmtypes::decode(e.data, m)) {
          body = m.child_frame_id;
        }
        out.pose_bodies[s.channel] = body;
      }
    } else if (fp == command_hash) {
      commands[s.channel].add(e.data, e.utime);
    } else if (fp == joint_state_hash) {
      joint_states[s.channel].add(e.data);
    } else if (fp == status_hash) {
      driftlab::estimator_status_t st;
      if (!lcmtypes::decode(e.data, st)) continue;
      auto es = std::find_if(out.estimators.begin(), out.estimators.end(),
                             [&](const EstimatorSeries& x) { return x.channel == s.channel; });
      if (es == out.estimators.end()) {
        es = out.estimators.insert(out.estimators.end(), EstimatorSeries{s.channel});
        es->inputs = st.input;
        const size_t n = st.input.size();
        es->fused.resize(n), es->stale.resize(n), es->future.resize(n), es->late.resize(n), es->outliers.resize(n);
      }
      if (st.input != es->inputs) continue;  // another estimator on the same channel: the first one's kept
      es->t.push_back(seconds_between(out.start_utime, e.utime));
      for (size_t i = 0; i < es->inputs.size(); ++i) {
        es->fused[i].push_back(st.fused[i]);
        es->stale[i].push_back(st.stale[i]);
        es->future[i].push_back(st.future[i]);
        es->late[i].push_back(st.late[i]);
        es->outliers[i].push_back(st.outliers[i]);
      }
    } else if (fp == loop_hash) {
      driftlab::loop_closure_t r;
      if (!lcmtypes::decode(e.data, r)) continue;
      auto ls =
          std::find_if(out.loops.begin(), out.loops.end(), [&](const LoopSeries& x) { return x.channel == s.channel; });
      if (ls == out.loops.end()) ls = out.loops.insert(out.loops.end(), LoopSeries{s.channel});
      ls->utime.push_back(r.header.utime);
      ls->old_utime.push_back(r.old_utime);
      ls->outcome.push_back(std::move(r.outcome));
    } else if (fp == image_hash) {
      driftlab::image_t image;
      if (!lcmtypes::decode(e.data, image) || image.encoding != "png" ||
          image.header.frame_id != "map") {
        continue;
      }
      auto m = std::find_if(out.maps.begin(), out.maps.end(), [&](const MapImage& x) { return x.channel == s.channel; });
      if (m == out.maps.end()) m = out.maps.insert(out.maps.end(), MapImage{s.channel});
      m->width = image.width;
      m->height = image.height;
      m->png = std::move(image.data);
    }
  }
  out.problems = reader->problems();
  out.arms = arm_series(commands, joint_states, out.start_utime);
  for (size_t k = 0; k < out.streams.size(); ++k) {
    StreamSeries& s = out.streams[k];
    s.arrival.reserve(arrivals[k].size());
    for (int64_t t : arrivals[k]) s.arrival.push_back(seconds_between(out.start_utime, t));
    if (!s.has_header || stamps[k].size() != arrivals[k].size()) {
      s.has_header = false;
      continue;
    }
    s.latency.reserve(stamps[k].size());
    for (size_t i = 0; i < stamps[k].size(); ++i) {
      s.latency.push_back(seconds_between(stamps[k][i], arrivals[k][i]) - Duration::from_us(ready_after[k]).seconds());
    }
  }
  std::sort(out.streams.begin(), out.streams.end(),
            [](const StreamSeries& a, const StreamSeries& b) { return a.channel < b.channel; });
  return out;
}

}  // namespace driftlab::analyzers
