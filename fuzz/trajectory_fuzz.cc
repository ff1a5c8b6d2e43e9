// libFuzzer target: any text read as a trajectory (TUM, KITTI, EuRoC, told apart or named) or as the SLAM
// benchmark's relations gives poses that are poses (finite, unit quaternions) or a one-line error naming the file,
// never a crash; what loads can be sorted, matched with itself and scored in every RPE mode.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "analyzers/relations.h"
#include "analyzers/time_offset.h"
#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"

namespace {

using namespace driftlab::analyzers;

void die(const std::string& what) {
  std::fprintf(stderr, "%s\n", what.c_str());
  std::abort();
}

void check_error(const driftlab::Error& e, const std::string& path) {
  if (e.message.rfind(path, 0) != 0 || e.message.find('\n') != std::string::npos) {
    die("error not one line naming " + path + ": " + e.message);
  }
}

void exercise(Trajectory t, bool offset) {
  for (size_t i = 0; i < t.size(); ++i) {
    if (!pose_problem(t.stamps[i], t.positions[i], t.orientations[i]).empty()) die("a loaded pose is no pose");
  }
  sort_by_stamp(t);
  const Matched m = t.stamped ? match_nearest(t, t, 0.01, 0.0) : Matched{t, t};
  if (m.ref.size() > 2000) return;  // all pairs by angle are quadratic
  const Alignment a = align(m, AlignmentType::kSim3);
  const Matched aligned{m.ref, a.problem.empty() ? apply(a, m.est) : m.est};
  ape(aligned);
  for (const auto unit : {DeltaUnit::kFrames, DeltaUnit::kMeters, DeltaUnit::kSeconds, DeltaUnit::kDegrees}) {
    for (const bool all : {false, true}) {
      RpeOptions o;
      o.unit = unit;
      o.delta = unit == DeltaUnit::kFrames ? 2 : 0.5;
      o.all_pairs = all;
      for (const auto& [i, j] : rpe(aligned, o).pairs) {
        if (i >= aligned.ref.size() || j >= aligned.ref.size() || i >= j) die("a pair out of range");
      }
    }
  }
  drift(aligned, {}, 1);
  if (offset) estimate_time_offset(t, t);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/driftlab-trajectory-fuzz-" + std::to_string(getpid()) + ".txt";
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return 0;
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  for (const auto format : {TrajectoryFormat::kAuto, TrajectoryFormat::kTum, TrajectoryFormat::kKitti,
                            TrajectoryFormat::kEuroc}) {
    auto t = load_trajectory(path, format);
    if (!t) {
      check_error(t.error(), path);
    } else {
      exercise(std::move(*t), format == TrajectoryFormat::kAuto);
    }
  }
  auto r = load_relations(path);
  if (!r) {
    check_error(r.error(), path);
  } else {
    Trajectory poses;
    for (const auto& rel : *r) {
      if (!std::isfinite(rel.t1) || !rel.translation.allFinite() || !rel.rotation.coeffs().allFinite()) {
        die("a relation that is not finite");
      }
      poses.push_back(rel.t1, rel.translation, rel.rotation);
    }
    sort_by_stamp(poses);
    RelationOptions o;
    o.odometry = &poses;
    relation_error(poses, *r, o);
  }
  return 0;
}
