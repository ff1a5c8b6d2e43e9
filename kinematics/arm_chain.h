// The kinematic chain of an arm, from a base link to a tip link of a RobotModel, with Orocos KDL (Debian's
// liborocos-kdl): forward kinematics, the geometric Jacobian and inverse kinematics. IK is KDL's Newton-Raphson
// position solver with joint limits (ChainIkSolverPos_NR_JL) over its weighted damped least-squares velocity solver
// (ChainIkSolverVel_wdls): each step solves the pose error by damped least squares and clamps to the joint limits.
// Why KDL (docs/kinematics.md): it is the kinematics library of ROS's robot_state_publisher and of MoveIt's KDL
// plugin, maintained and packaged by Debian, and gives FK, Jacobians and limit-aware IK tested by others; what it
// lacks, a URDF reader (kdl_parser is ROS's, not Debian's), is the small conversion in arm_chain.cc.
// Thread-safety: an ArmChain keeps solver workspaces; use one per thread (copies are cheap to create()).
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "core/result.h"
#include "kinematics/robot_model.h"

namespace driftlab::kinematics {

struct IkOptions {
  int max_iterations = 100;
  double tolerance = 1e-6;  ///< on the pose error's twist norm [m, rad]
  double damping = 0.01;    ///< damped least squares' lambda
};

struct IkResult {
  bool converged = false;
  Eigen::VectorXd q;          ///< the solution, within the joint limits [rad]
  double position_error = 0;  ///< of fk(q) from the target [m]
  double angle_error = 0;     ///< [rad]
};

class ArmChain {
 public:
  /// The moving joints from `base` to `tip`. With `need_limits`, every one must be revolute or prismatic with
  /// position, velocity and effort limits (a joint trajectory controller needs them); errors name the file, line
  /// and joint.
  static Result<ArmChain> create(const RobotModel& model, const std::string& base, const std::string& tip,
                                 bool need_limits);
  ArmChain(ArmChain&&) noexcept;
  ArmChain& operator=(ArmChain&&) noexcept;
  ~ArmChain();

  const std::string& base() const;
  const std::string& tip() const;
  int dof() const;
  const std::vector<std::string>& joint_names() const;
  const std::vector<JointLimits>& limits() const;

  /// The tip's pose in the base link's frame at joint positions q (dof() of them) [m, rad].
  Eigen::Isometry3d fk(const Eigen::VectorXd& q) const;
  /// The geometric Jacobian at q, in the base frame, reference point at the tip: rows vx vy vz wx wy wz.
  Eigen::MatrixXd jacobian(const Eigen::VectorXd& q) const;
  /// Joint positions that put the tip at `target` (in the base frame), starting from `seed`.
  IkResult ik(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, const IkOptions& options = {}) const;

 private:
  struct Impl;
  explicit ArmChain(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// The position and angle between two poses [m, rad].
double position_distance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);
double angle_distance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

}  // namespace driftlab::kinematics
