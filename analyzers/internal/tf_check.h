// TF tree checks for `driftlab diagnose`: frames missing or disconnected from the root, frames with two parents,
// transforms stamped in the future, dynamic transforms stamped behind the data they are composed with (the data
// must wait, or extrapolate, beyond the transform's period: "extrapolation into the future"), that lag it (no
// transform as new as a message's stamp within the transform's period and 50 ms of its arrival) or go stale, and
// static transforms republished with other values.
// Internal to analyzers (used by timing.cc). Thread-safety: plain values.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzers/timing.h"

namespace driftlab::analyzers::internal {

/// Whether a channel of tf_t holds static transforms: its name contains "static" in any case (TF_STATIC,
/// ROS's /tf_static).
bool is_static_tf_channel(std::string_view channel);

class TfCheck {
 public:
  /// A driftlab.tf_t message on `channel` that arrived at arrival [us].
  void add_tf(const std::string& channel, std::span<const uint8_t> data, int64_t arrival, bool is_static);
  /// The messages of a stream channel in frame `frame`: their stamps and arrivals [us], in arrival order; once per
  /// channel and frame. Kept as views, not copied (a long log's streams hold millions): they must stay valid and
  /// unchanged until finish().
  void add_data(const std::string& channel, const std::string& frame, std::span<const int64_t> stamps,
                std::span<const int64_t> arrivals);
  /// to_arrival(channel, stamp) maps a stamp of the channel's clock onto the recorder's (its clock domain's).
  TfDiagnosis finish(const std::function<int64_t(const std::string&, int64_t)>& to_arrival) const;

 private:
  struct Edge {
    std::string parent;
    std::string channel;  // the first that carried it
    bool is_static = false;
    std::vector<int64_t> arrival;  // dynamic: in arrival order
    std::vector<int64_t> newest;   // newest stamp received by then
    std::vector<int64_t> stamps;   // each transform's stamp, in arrival order
    int64_t out_of_order = 0;      // stamped older than the newest already received
    bool static_changed = false;
    double static_values[7] = {};  // translation, rotation (w, x, y, z)
    bool have_static = false;
    std::vector<std::string> other_parents;
  };
  struct Use {
    int64_t stamp, arrival;
  };
  struct Uses {  // a channel's messages: views of what add_data was given
    std::span<const int64_t> stamps, arrivals;
    size_t size() const { return stamps.size(); }
    Use operator[](size_t i) const { return {stamps[i], arrivals[i]}; }
  };
  std::map<std::string, Edge> edges_;                         // by child frame
  std::map<std::pair<std::string, std::string>, Uses> uses_;  // (channel, frame) -> messages
};

}  // namespace driftlab::analyzers::internal
