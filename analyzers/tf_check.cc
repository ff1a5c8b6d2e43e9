#include "analyzers/internal/tf_check.h"

#include <cctype>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "core/time.h"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers::internal {
namespace {
constexpr int64_t kFutureToleranceUs = 1000;
/// How long a consumer may wait for a transform as new as a message's stamp before it fails.
constexpr int64_t kWaitUs = 50000;
std::string quoted(const std::string& frame) { return "'" + frame + "'"; }
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

void TfCheck::add_tf(std::span<const uint8_t> data, int64_t arrival, bool is_static) {
  driftlab::tf_t tf;
  if (!lcmtypes::decode(data, tf)) return;
  for (const auto& t : tf.transforms) {
    Edge& e = edges_[t.child_frame_id];
    if (e.parent.empty()) {
      e.parent = t.header.frame_id;
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
    if (t.header.utime > arrival + kFutureToleranceUs) ++e.future_stamps;
    e.newest.push_back(e.newest.empty() ? t.header.utime : std::max(e.newest.back(), t.header.utime));
    e.arrival.push_back(arrival);
  }
}

void TfCheck::add_data(const std::string& channel, const std::string& frame, std::span<const int64_t> stamps,
                       std::span<const int64_t> arrivals) {
  if (frame.empty() || stamps.empty()) return;
  auto& uses = uses_[{channel, frame}];
  for (size_t i = 0; i < stamps.size(); ++i) uses.push_back({stamps[i], arrivals[i]});
}

TfDiagnosis TfCheck::finish() const {
  TfDiagnosis d;
  if (edges_.empty()) return d;  // no TF in this log: nothing to check
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
  char buf[512];
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
    if (e.future_stamps > 0) {
      std::snprintf(buf, sizeof(buf), "%lld transforms %s -> %s are stamped in the future of their arrival",
                    static_cast<long long>(e.future_stamps), quoted(e.parent).c_str(), quoted(child).c_str());
      d.problems.push_back(buf);
    }
  }
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
      // Within 50 ms of the message's arrival, had a transform at or after its stamp arrived?
      int64_t lagging = 0;
      for (const Use& u : uses) {
        const auto at =
            std::upper_bound(e->arrival.begin(), e->arrival.end(), u.arrival + kWaitUs) - e->arrival.begin();
        if (at == 0 || e->newest[static_cast<size_t>(at - 1)] < u.stamp) ++lagging;
      }
      if (lagging * 10 > static_cast<int64_t>(uses.size())) {
        std::snprintf(buf, sizeof(buf),
                      "%lld of %zu %s messages find no transform %s -> %s as new as their stamp within 50 ms of "
                      "arriving (\"extrapolation into the future\")",
                      static_cast<long long>(lagging), uses.size(), channel.c_str(), quoted(e->parent).c_str(),
                      quoted(child).c_str());
        d.problems.push_back(buf);
      }
      // Stale: the transform stops while the data goes on.
      const int64_t last_data = uses.back().stamp;
      if (!e->newest.empty() && last_data - e->newest.back() > 1000000) {
        std::snprintf(buf, sizeof(buf),
                      "transform %s -> %s goes stale: its last stamp is %.1f s before the last %s message",
                      quoted(e->parent).c_str(), quoted(child).c_str(),
                      Duration::from_us(last_data - e->newest.back()).seconds(), channel.c_str());
        d.problems.push_back(buf);
      }
    }
  }
  return d;
}

}  // namespace driftlab::analyzers::internal
