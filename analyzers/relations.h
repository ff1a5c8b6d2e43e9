// The SLAM benchmark's relation error (R. Kümmerle, B. Steder, C. Dornhege, M. Ruhnke, G. Grisetti, C. Stachniss,
// A. Kleiner: "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27, 2009): an estimate is scored
// by how well it reproduces relative poses between pairs of its own poses, the relations, which people checked by
// hand; no global frame and no alignment. The statistics are those the benchmark's metric evaluator reports and
// the paper's tables give: mean, standard deviation and maximum of the absolute and of the squared translation
// and rotation errors. Thread-safety: pure functions over values.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::analyzers {

/// One relation: the pose stamped t2 in the frame of the pose stamped t1.
struct Relation {
  double t1 = 0, t2 = 0;                                       ///< [s]
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();       ///< [m]
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

/// A relations file as the benchmark publishes it: one relation a line, "t1 t2 x y z roll pitch yaw" (metres,
/// radians; the rotation is yaw about z, then pitch about y, then roll about x: R = Rz(yaw) Ry(pitch) Rx(roll)),
/// separated by spaces or tabs; blank lines and '#' comments skipped. Errors name the file and the line.
Result<std::vector<Relation>> load_relations(const std::string& path);

struct RelationOptions {
  /// A relation's stamp takes the estimate's pose with the nearest stamp when it is at most this far [s].
  double max_dt = 0.01;
  /// Raw odometry (sorted by stamp), or null. With it, a stamp with no estimate pose within max_dt takes the
  /// nearest estimate pose carried to the stamp by the odometry's motion between the two stamps, as the metric
  /// evaluator's -o option does for SLAM logs that hold only some of the scans; without it such a relation is
  /// left out. The odometry is interpolated (linear in position, slerp in rotation) between its two poses around a
  /// stamp when they are at most kMaxOdometryGap apart.
  const Trajectory* odometry = nullptr;
};

/// Wheel odometry comes at 10 Hz or more; two poses further apart than this [s] are a dropout, not something
/// to interpolate across.
inline constexpr double kMaxOdometryGap = 1.0;

/// Mean, standard deviation (sample, n - 1: the benchmark's convention, also Cartographer's implementation of the
/// metric) and maximum.
struct RelationStats {
  double mean = 0, std = 0, max = 0;
};

struct RelationResult {
  size_t relations = 0;   ///< in the file [count]
  size_t used = 0;        ///< evaluated: both stamps found a pose [count]
  size_t bridged = 0;     ///< of the used, those with a pose carried by odometry [count]
  double max_bridge_s = 0;  ///< the longest time a pose was carried by odometry [s]
  RelationStats trans_m, trans_sq_m2, rot_deg, rot_sq_deg2;
  /// Per used relation, in file order: its line in the relations (0-based index) and its errors.
  std::vector<size_t> index;
  PoseArray<double> trans_errors_m;
  PoseArray<double> rot_errors_deg;
};

/// The error of each relation is E = D*^-1 D, D = X1^-1 X2 the estimate's relative pose and D* the relation's
/// (the paper's delta (-) delta*): its translation's norm [m] and its rotation's angle [deg]. est must be sorted
/// by stamp.
RelationResult relation_error(const Trajectory& est, const std::vector<Relation>& relations,
                              const RelationOptions& options = {});

}  // namespace driftlab::analyzers
