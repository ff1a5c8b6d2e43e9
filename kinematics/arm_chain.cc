#include "kinematics/arm_chain.h"

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_wdls.hpp>
#include <kdl/chainjnttojacsolver.hpp>

#include <cmath>

namespace driftlab::kinematics {
namespace {

KDL::Frame to_kdl(const Eigen::Isometry3d& t) {
  const Eigen::Matrix3d r = t.rotation();
  return KDL::Frame(KDL::Rotation(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2)),
                    KDL::Vector(t.translation().x(), t.translation().y(), t.translation().z()));
}

Eigen::Isometry3d to_eigen(const KDL::Frame& f) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) t.linear()(r, c) = f.M(r, c);
    t.translation()[r] = f.p[r];
  }
  return t;
}

KDL::Vector to_kdl(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

KDL::JntArray to_kdl(const Eigen::VectorXd& q) {
  KDL::JntArray a(static_cast<unsigned>(q.size()));
  a.data = q;
  return a;
}

}  // namespace

struct ArmChain::Impl {
  std::string base, tip;
  std::vector<std::string> names;
  std::vector<JointLimits> limits;
  KDL::Chain chain;
  KDL::JntArray q_min, q_max;
  // Solvers keep references to the chain: built after it, in place.
  std::unique_ptr<KDL::ChainFkSolverPos_recursive> fk;
  std::unique_ptr<KDL::ChainJntToJacSolver> jac;
  std::unique_ptr<KDL::ChainIkSolverVel_wdls> ik_vel;
  std::unique_ptr<KDL::ChainIkSolverPos_NR_JL> ik_pos;
  IkOptions ik_options;  // what ik_pos was built with
  void make_ik(const IkOptions& o) {
    ik_vel = std::make_unique<KDL::ChainIkSolverVel_wdls>(chain);
    ik_vel->setLambda(o.damping);
    ik_pos = std::make_unique<KDL::ChainIkSolverPos_NR_JL>(chain, q_min, q_max, *fk, *ik_vel,
                                                           static_cast<unsigned>(o.max_iterations), o.tolerance);
    ik_options = o;
  }
};

ArmChain::ArmChain(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ArmChain::ArmChain(ArmChain&&) noexcept = default;
ArmChain& ArmChain::operator=(ArmChain&&) noexcept = default;
ArmChain::~ArmChain() = default;

Result<ArmChain> ArmChain::create(const RobotModel& model, const std::string& base, const std::string& tip,
                                  bool need_limits) {
  auto path = model.path(base, tip);
  if (!path) return path.error();
  auto impl = std::make_unique<Impl>();
  impl->base = base;
  impl->tip = tip;
  // kdl_parser's mapping: a segment per URDF joint, its KDL joint at the URDF joint's origin with the axis
  // expressed in the parent link's frame, its tip frame the joint origin (the child link's frame at zero).
  for (const ModelJoint* j : *path) {
    const KDL::Frame origin = to_kdl(j->origin);
    KDL::Joint joint;
    switch (j->type) {
      case JointType::kFixed: joint = KDL::Joint(j->name, KDL::Joint::None); break;
      case JointType::kRevolute:
      case JointType::kContinuous:
        joint = KDL::Joint(j->name, origin.p, origin.M * to_kdl(j->axis), KDL::Joint::RotAxis);
        break;
      case JointType::kPrismatic:
        joint = KDL::Joint(j->name, origin.p, origin.M * to_kdl(j->axis), KDL::Joint::TransAxis);
        break;
      case JointType::kOther: return Error{model.where(*j) + ": a planar or floating joint cannot be part of an arm"};
    }
    impl->chain.addSegment(KDL::Segment(j->child, joint, origin));
    if (!j->moves()) continue;
    if (need_limits) {
      if (j->type == JointType::kContinuous) {
        return Error{model.where(*j) +
                     ": is continuous, without position limits; the joint trajectory controller needs position, "
                     "velocity and effort limits (make it revolute with a <limit lower upper velocity effort>)"};
      }
      if (!j->limits.has_position || !(j->limits.velocity > 0) || !(j->limits.effort > 0)) {
        return Error{model.where(*j) +
                     ": has no <limit> with lower, upper, velocity > 0 and effort > 0; the joint trajectory "
                     "controller needs them"};
      }
    }
    impl->names.push_back(j->name);
    impl->limits.push_back(j->limits);
  }
  if (impl->names.empty()) {
    return Error{model.origin() + ": no moving joint between link '" + base + "' and link '" + tip + "'"};
  }
  const auto n = static_cast<unsigned>(impl->names.size());
  impl->q_min.resize(n);
  impl->q_max.resize(n);
  for (unsigned i = 0; i < n; ++i) {
    const JointLimits& l = impl->limits[i];
    impl->q_min(i) = l.has_position ? l.lower : -1e9;
    impl->q_max(i) = l.has_position ? l.upper : 1e9;
  }
  impl->fk = std::make_unique<KDL::ChainFkSolverPos_recursive>(impl->chain);
  impl->jac = std::make_unique<KDL::ChainJntToJacSolver>(impl->chain);
  impl->make_ik(IkOptions{});
  return ArmChain(std::move(impl));
}

const std::string& ArmChain::base() const { return impl_->base; }
const std::string& ArmChain::tip() const { return impl_->tip; }
int ArmChain::dof() const { return static_cast<int>(impl_->names.size()); }
const std::vector<std::string>& ArmChain::joint_names() const { return impl_->names; }
const std::vector<JointLimits>& ArmChain::limits() const { return impl_->limits; }

Eigen::Isometry3d ArmChain::fk(const Eigen::VectorXd& q) const {
  KDL::Frame f;
  impl_->fk->JntToCart(to_kdl(q), f);
  return to_eigen(f);
}

Eigen::MatrixXd ArmChain::jacobian(const Eigen::VectorXd& q) const {
  KDL::Jacobian j(static_cast<unsigned>(q.size()));
  impl_->jac->JntToJac(to_kdl(q), j);
  return j.data;
}

IkResult ArmChain::ik(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, const IkOptions& options) const {
  const IkOptions& o = impl_->ik_options;
  if (o.max_iterations != options.max_iterations || o.tolerance != options.tolerance || o.damping != options.damping) {
    impl_->make_ik(options);
  }
  IkResult r;
  KDL::JntArray out(static_cast<unsigned>(seed.size()));
  // The seed inside the limits: the solver clamps its steps, not its start.
  Eigen::VectorXd start = seed.cwiseMax(impl_->q_min.data).cwiseMin(impl_->q_max.data);
  const int status = impl_->ik_pos->CartToJnt(to_kdl(start), to_kdl(target), out);
  r.q = out.data;
  const Eigen::Isometry3d reached = fk(r.q);
  r.position_error = position_distance(reached, target);
  r.angle_error = angle_distance(reached, target);
  r.converged = status >= 0;
  return r;
}

double position_distance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

double angle_distance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle();
}

}  // namespace driftlab::kinematics
