#include "analyzers/internal/tf_check.h"

#include <cctype>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <set>

#include "analyzers/internal/channel_samples.h"
#include "core/time.h"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers::internal {
namespace {
constexpr int64_t kFutureToleranceUs = 1000;
/// How long a consumer may wait, beyond one period of a transform, for one as new as a message's stamp before it
/// fails; and how far behind the data a transform may be stamped.
constexpr int64_t kWaitUs = 50000;
std::string quoted(const std::string& frame) { return "'" + frame + "'"; }

/// The median interval between a transform's distinct stamps [us]; 0 with fewer than two.
int64_t period_of(std::vector<int64_t> stamps) {
  std::sort(stamps.begin(), stamps.end());
  stamps.erase(std::unique(stamps.begin(), stamps.end()), stamps.end());
  if (stamps.size() < 2) return 0;
  std::vector<int64_t> gaps;
  for (size_t i = 1; i < stamps.size(); ++i) gaps.push_back(stamps[i] - stamps[i - 1]);
  std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
  return gaps[gaps.size() / 2];
}

}  // namespace

bool is_static_tf_channel(std::string_view channel) {
  constexpr std::string_view kStatic = "static";
  for (size_t i = 0; i + kStatic.size() <= channel.size(); ++i) {
    bool match = true;
    for (size_t k = 0; k < kStatic.size() && match; ++k) {
      match = std::tolower(static_cast<unsigned char>(channel[i + k])) == kStatic[k];
    }
    if (match) return true;
  }
  return false;
}

void TfCheck::add_tf(const std::string& channel, std::span<const uint8_t> data, int64_t arrival, bool is_static) {
  driftlab::tf_t tf;
  if (!lcmtypes::decode(data, tf)) return;
  for (const auto& t : tf.transforms) {
    Edge& e = edges_[t.child_frame_id];
    if (e.parent.empty()) {
      e.parent = t.header.frame_id;
      e.channel = channel;
    } else if (e.parent != t.header.frame_id &&
               std::find(e.other_parents.begin(), e.other_parents.end(), t.header.frame_id) == e.other_parents.end()) {
      e.other_parents.push_back(t.header.frame_id);
    }
    e.is_static = e.is_static || is_static;
    if (is_static) {
      const double v[7] = {t.translation.x, t.translation.y, t.translation.z, t.rotation.w,
                           t.rotation.x,    t.rotation.y,    t.rotation.z};
      if (e.have_static) {
        for (int i = 0; i < 7; ++i) e.static_changed = e.static_changed || std::abs(v[i] - e.static_values[i]) > 1e-9;
      }
      std::copy(v, v + 7, e.static_values);
      e.have_static = true;
      continue;
    }
    if (!e.newest.empty() && t.header.utime < e.newest.back()) ++e.out_of_order;
    e.newest.push_back(e.newest.empty() ? t.header.utime : std::max(e.newest.back(), t.header.utime));
    e.stamps.push_back(t.header.utime);
    e.arrival.push_back(arrival);
  }
}

void TfCheck::add_data(const std::string& channel, const std::string& frame, std::span<const int64_t> stamps,
                       std::span<const int64_t> arrivals) {
  if (frame.empty() || stamps.empty()) return;
  const size_t n = std::min(stamps.size(), arrivals.size());
  uses_[{channel, frame}] = {stamps.first(n), arrivals.first(n)};
}

TfDiagnosis TfCheck::finish(const std::function<int64_t(const std::string&, int64_t)>& to_arrival) const {
  TfDiagnosis d;
  if (edges_.empty()) return d;  // no TF in this log: nothing to check
  // Each transform: its rate, order and age on arrival (its stamps on the recorder's clock).
  struct Ahead {
    size_t count = 0;
    Distribution how_far;  // how far ahead of their arrival [s]
  };
  std::map<std::string, Ahead> ahead_by;  // by child: the transforms stamped ahead of their arrival
  for (const auto& [child, e] : edges_) {
    TfEdge edge;
    edge.parent = e.parent;
    edge.child = child;
    edge.channel = e.channel;
    edge.is_static = e.is_static;
    edge.out_of_order = e.out_of_order;
    edge.count = static_cast<int64_t>(e.stamps.size());
    if (e.is_static) {
      edge.count = std::max<int64_t>(edge.count, 1);
    } else {
      const int64_t period = period_of(e.stamps);
      if (period > 0) edge.rate_hz = 1 / Duration::from_us(period).seconds();
      Array<double> age, ahead;
      for (size_t k = 0; k < e.stamps.size(); ++k) {
        const int64_t stamp = to_arrival(e.channel, e.stamps[k]);
        age.push_back(seconds_between(stamp, e.arrival[k]));
        if (stamp > e.arrival[k] + kFutureToleranceUs) {
          ++edge.ahead;
          ahead.push_back(seconds_between(e.arrival[k], stamp));
        }
      }
      edge.age_s = distribution(std::move(age));
      if (!ahead.empty()) ahead_by[child] = {ahead.size(), distribution(std::move(ahead))};
    }
    d.edges.push_back(std::move(edge));
  }
  std::set<std::string> frames;
  for (const auto& [child, e] : edges_) {
    frames.insert(child);
    frames.insert(e.parent);
  }
  d.frames.assign(frames.begin(), frames.end());
  for (const auto& f : frames) {
    if (edges_.count(f) == 0) d.roots.push_back(f);
  }
  auto root_of = [&](std::string f) {
    for (size_t hops = 0; hops <= edges_.size(); ++hops) {
      const auto it = edges_.find(f);
      if (it == edges_.end()) return f;
      f = it->second.parent;
    }
    return std::string();  // a cycle
  };
  char buf[1024];
  if (d.roots.size() > 1) {
    std::string list;
    for (const auto& r : d.roots) list += (list.empty() ? "" : ", ") + quoted(r);
    d.problems.push_back("the TF tree is split into " + std::to_string(d.roots.size()) + " trees with roots " + list +
                         ": frames of different trees cannot be transformed into each other");
  }
  for (const auto& [child, e] : edges_) {
    for (const auto& other : e.other_parents) {
      d.problems.push_back("frame " + quoted(child) + " has two parents, " + quoted(e.parent) + " and " + quoted(other));
    }
    if (root_of(child).empty()) d.problems.push_back("frame " + quoted(child) + " is part of a cycle");
    if (e.static_changed) {
      d.problems.push_back("static transform " + quoted(e.parent) + " -> " + quoted(child) +
                           " was republished with different values");
    }
    // Most of a transform's stamps ahead of their arrival (a few are a delivery faster than the clock's reference).
    if (const auto it = ahead_by.find(child); it != ahead_by.end() && it->second.count * 2 > e.stamps.size()) {
      // Post-dated: a lookup up to that far past the newest transform succeeds with it instead of failing (AMCL and
      // slam_toolbox do so on purpose, by their transform_tolerance): data is transformed with a stale estimate.
      const std::string& frame = child;  // a structured binding cannot be captured (C++17)
      const TfEdge& edge =
          *std::find_if(d.edges.begin(), d.edges.end(), [&](const TfEdge& x) { return x.child == frame; });
      std::snprintf(buf, sizeof(buf),
                    "transform %s -> %s (%s) is stamped %.1f ms ahead of its arrival (median; up to %.1f ms, %lld of "
                    "%lld transforms): post-dated, as a transform_tolerance does, so lookups up to that far past "
                    "its last estimate succeed with a stale one",
                    quoted(e.parent).c_str(), quoted(child).c_str(), e.channel.c_str(), it->second.how_far.p50 * 1e3,
                    it->second.how_far.max * 1e3, static_cast<long long>(edge.ahead),
                    static_cast<long long>(edge.count));
      d.problems.push_back(buf);
    }
  }
  // Per dynamic transform, the data composed with it: the stamps' check of each channel.
  std::map<std::string, std::vector<TfStampCheck>> by_edge;  // by child frame
  std::map<std::string, std::vector<std::string>> lagging;   // by child frame: the lagging problems
  std::map<const Edge*, double> tf_latency_of;               // each dynamic transform's median latency [s]
  for (const auto& [key, uses] : uses_) {
    const auto& [channel, frame] = key;
    if (frames.count(frame) == 0) {
      d.problems.push_back("frame " + quoted(frame) + " of " + channel + " is not in the TF tree");
      continue;
    }
    // The dynamic transforms between the frame and its root.
    std::vector<std::pair<std::string, const Edge*>> chain;
    std::string f = frame;
    for (size_t hops = 0; hops <= edges_.size(); ++hops) {
      const auto it = edges_.find(f);
      if (it == edges_.end()) break;
      if (!it->second.is_static) chain.emplace_back(it->first, &it->second);
      f = it->second.parent;
    }
    for (const auto& [child, e] : chain) {
      if (e->arrival.empty()) continue;
      const int64_t period = period_of(e->stamps);
      // At each message's arrival: the newest transform received, and when the first as new as its stamp came.
      TfStampCheck c;
      c.parent = e->parent;
      c.child = child;
      c.tf_channel = e->channel;
      c.channel = channel;
      c.frame = frame;
      c.period_s = Duration::from_us(period).seconds();
      Array<double> leads, waits;
      int64_t late = 0;
      // The messages come in arrival order, their stamps nearly so: each search goes on from the last answer while
      // its key does not go back (the same answer as a binary search over the whole, in a step or two).
      const bool arrivals_sorted = std::is_sorted(e->arrival.begin(), e->arrival.end());
      auto at = e->arrival.begin();
      auto as_new_it = e->newest.begin();  // newest is the running maximum: sorted
      int64_t last_arrival = INT64_MIN, last_stamp = INT64_MIN;
      for (size_t k = 0; k < uses.size(); ++k) {
        const Use u = uses[k];
        if (arrivals_sorted && u.arrival >= last_arrival) {
          while (at != e->arrival.end() && *at <= u.arrival) ++at;
        } else {
          at = std::upper_bound(e->arrival.begin(), e->arrival.end(), u.arrival);
        }
        if (u.stamp >= last_stamp) {
          while (as_new_it != e->newest.end() && *as_new_it < u.stamp) ++as_new_it;
        } else {
          as_new_it = std::lower_bound(e->newest.begin(), e->newest.end(), u.stamp);
        }
        last_arrival = u.arrival;
        last_stamp = u.stamp;
        const auto before = at - e->arrival.begin();
        if (before > 0) leads.push_back(seconds_between(e->newest[static_cast<size_t>(before - 1)], u.stamp));
        const auto as_new = as_new_it - e->newest.begin();
        if (as_new == static_cast<std::ptrdiff_t>(e->newest.size())) {
          ++c.never;
          ++late;
          continue;
        }
        const int64_t wait = std::max<int64_t>(0, e->arrival[static_cast<size_t>(as_new)] - u.arrival);
        waits.push_back(Duration::from_us(wait).seconds());
        if (wait > period + kWaitUs) ++late;
      }
      c.messages = static_cast<int64_t>(leads.size());
      if (!leads.empty()) {
        Array<double> copy = leads;
        c.offset_s = quantile(copy, 0.01);
      }
      c.lead_s = distribution(std::move(leads));
      c.wait_s = distribution(std::move(waits));
      // The transform's own median latency, the same for every channel composed with it: worked out once.
      auto [known, fresh] = tf_latency_of.try_emplace(e, 0.0);
      if (fresh) {
        Array<double> tf_latency;
        for (size_t k = 0; k < e->arrival.size(); ++k) {
          tf_latency.push_back(seconds_between(to_arrival(e->channel, e->stamps[k]), e->arrival[k]));
        }
        known->second = median(std::move(tf_latency));
      }
      c.tf_latency_s = known->second;
      Array<double> data_latency;
      for (size_t k = 0; k < uses.size(); ++k) {
        const Use u = uses[k];
        data_latency.push_back(seconds_between(to_arrival(channel, u.stamp), u.arrival));
      }
      c.data_latency_s = median(std::move(data_latency));
      // Within its period and 50 ms of the message's arrival, had a transform at or after its stamp arrived?
      if (late * 10 > static_cast<int64_t>(uses.size())) {
        std::snprintf(buf, sizeof(buf),
                      "%lld of %zu %s messages find no transform %s -> %s as new as their stamp within %.0f ms of "
                      "arriving (its %.0f ms period and 50 ms): \"extrapolation into the future\"",
                      static_cast<long long>(late), uses.size(), channel.c_str(), quoted(e->parent).c_str(),
                      quoted(child).c_str(), Duration::from_us(period + kWaitUs).seconds() * 1e3, c.period_s * 1e3);
        lagging[child].push_back(buf);
      }
      // Stale: the transform stops while the data goes on.
      const int64_t last_data = uses.stamps.back();
      if (!e->newest.empty() && last_data - e->newest.back() > 1000000) {
        std::snprintf(buf, sizeof(buf),
                      "transform %s -> %s goes stale: its last stamp is %.1f s before the last %s message",
                      quoted(e->parent).c_str(), quoted(child).c_str(), seconds_between(e->newest.back(), last_data),
                      channel.c_str());
        d.problems.push_back(buf);
      }
      by_edge[child].push_back(c);
    }
  }
  // A transform stamped behind the data it is composed with: one problem per transform, named by the data in its
  // child frame (composed with it directly: odometry in 'odom' with 'map' -> 'odom'), else the busiest channel.
  for (auto& [child, checks] : by_edge) {
    std::vector<const TfStampCheck*> behind;
    for (const TfStampCheck& c : checks) {
      if (c.messages > 0 && c.offset_s > Duration::from_us(kWaitUs).seconds()) behind.push_back(&c);
    }
    if (behind.empty()) {
      for (auto& p : lagging[child]) d.problems.push_back(std::move(p));
    } else {
      auto in_child_frame = [](const TfStampCheck* c) { return c->frame == c->child; };
      const TfStampCheck* head = *std::max_element(behind.begin(), behind.end(), [&](const auto* a, const auto* b) {
        return std::pair(in_child_frame(a), a->messages) < std::pair(in_child_frame(b), b->messages);
      });
      std::string others;
      for (const TfStampCheck* c : behind) {
        if (c != head) others += (others.empty() ? "" : ", ") + c->channel;
      }
      std::snprintf(buf, sizeof(buf),
                    "transform %s -> %s (%s) is %.1f ms behind %s, which it is composed with, beyond its %.0f ms "
                    "period: when a message arrives, a lookup at its stamp lies %.0f to %.0f ms past the newest "
                    "transform (\"extrapolation into the future\"); %s's stamps are %.1f ms older than their "
                    "arrival, %s's %.1f ms (a clock behind, a stamp taken early, or a slow transport)",
                    quoted(head->parent).c_str(), quoted(child).c_str(), head->tf_channel.c_str(), head->offset_s * 1e3,
                    head->channel.c_str(), head->period_s * 1e3, head->offset_s * 1e3, head->lead_s.max * 1e3,
                    head->tf_channel.c_str(), head->tf_latency_s * 1e3, head->channel.c_str(),
                    head->data_latency_s * 1e3);
      d.problems.push_back(std::string(buf) + (others.empty() ? "" : "; the same for " + others));
    }
    for (auto& c : checks) d.stamps.push_back(std::move(c));
  }
  return d;
}

}  // namespace driftlab::analyzers::internal
