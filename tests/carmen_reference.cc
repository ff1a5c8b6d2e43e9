#include "tests/carmen_reference.h"

#include <map>
#include <vector>

#include "core/log_reader.h"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::test {

Result<analyzers::Trajectory> corrected_at_raw_stamps(const std::string& raw_log, const std::string& corrected_log) {
  std::map<std::vector<float>, int64_t> stamp_of;
  auto raw = LogReader::open(raw_log);
  if (!raw) return raw.error();
  Event e;
  while (raw->next(e)) {
    laser_scan_t s;
    if (e.channel != "/scan" || !lcmtypes::decode(e.data, s)) continue;
    if (!stamp_of.emplace(s.ranges, s.header.utime).second) {
      return Error{raw_log + ": two scans with the same readings: matching by readings would be ambiguous"};
    }
  }
  std::vector<std::vector<float>> scans;
  std::vector<pose_t> poses;
  auto corrected = LogReader::open(corrected_log);
  if (!corrected) return corrected.error();
  while (corrected->next(e)) {
    laser_scan_t s;
    pose_t p;
    if (e.channel == "FLASER" && lcmtypes::decode(e.data, s)) scans.push_back(s.ranges);
    if (e.channel == "FLASER_POSE" && lcmtypes::decode(e.data, p)) poses.push_back(p);
  }
  if (scans.size() != poses.size() || scans.empty()) {
    return Error{corrected_log + ": " + std::to_string(scans.size()) + " scans and " + std::to_string(poses.size()) +
                 " poses on FLASER and FLASER_POSE (one pose per FLASER line expected)"};
  }
  analyzers::Trajectory t;
  for (size_t i = 0; i < scans.size(); ++i) {
    const auto it = stamp_of.find(scans[i]);
    if (it == stamp_of.end()) return Error{corrected_log + ": scan " + std::to_string(i) + " is not in " + raw_log};
    const auto& p = poses[i];
    t.push_back(static_cast<double>(it->second) * 1e-6, {p.position.x, p.position.y, p.position.z},
                {p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z});
  }
  analyzers::sort_by_stamp(t);
  return t;
}

}  // namespace driftlab::test
