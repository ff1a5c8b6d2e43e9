#include "sim/internal/arm_loop.h"

#include <algorithm>
#include <cmath>

#include "driftlab/joint_state_t.hpp"
#include "driftlab/joint_trajectory_state_t.hpp"
#include "driftlab/robot_description_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::sim {
namespace {

driftlab::transform_t transform(const std::string& parent, const std::string& child, const Eigen::Isometry3d& p,
                                int64_t now) {
  driftlab::transform_t t{};
  t.header.utime = now;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.translation = {p.translation().x(), p.translation().y(), p.translation().z()};
  const Eigen::Quaterniond q(p.rotation());
  t.rotation = {q.w(), q.x(), q.y(), q.z()};
  return t;
}

}  // namespace

ArmLoop::ArmLoop(const Scenario& sc, Robot& robot, kinematics::RobotModel model, controller::ArmCommander commander,
                 controller::JointTrajectoryController jtc, std::vector<int> index)
    : c_(sc.arm),
      start_utime_(sc.start_utime),
      robot_(robot),
      model_(std::move(model)),
      commander_(std::move(commander)),
      jtc_(std::move(jtc)),
      index_(std::move(index)) {
  for (const SensorConfig& s : sc.sensors) {
    if (s.type == SensorType::kJointState) joint_state_channel_ = s.channel;
  }
}

Result<std::unique_ptr<ArmLoop>> ArmLoop::create(const Scenario& sc, Robot& robot) {
  const ArmConfig& c = sc.arm;
  auto model = kinematics::RobotModel::load(sc.urdf_path);
  if (!model) return model.error();
  auto chain = kinematics::ArmChain::create(*model, c.commander.base_link, c.commander.tip_link, true);
  if (!chain) return chain.error();
  bool has_joint_states = false;
  for (const SensorConfig& s : sc.sensors) has_joint_states = has_joint_states || s.type == SensorType::kJointState;
  if (!has_joint_states) {
    return Error{sc.path +
                 ": arm: the commander reads the joints from a joint_state sensor, and the scenario has none"};
  }
  std::vector<int> index;
  std::map<std::string, double> home;
  for (size_t i = 0; i < chain->joint_names().size(); ++i) {
    const std::string& name = chain->joint_names()[i];
    index.push_back(robot.joint_index(name));
    if (index.back() < 0) return Error{sc.path + ": arm: joint '" + name + "' is not a hinge of the simulated robot"};
    if (i < c.commander.home.size()) home[name] = c.commander.home[i];
  }
  controller::JointTrajectoryController jtc(chain->joint_names(), chain->limits(), c.controller);
  auto commander = controller::ArmCommander::create(std::move(*chain), c.commander);
  if (!commander) return Error{sc.path + ": arm: " + commander.error().message};
  if (Status s = robot.set_initial_positions(home); !s) return Error{sc.path + ": arm: " + s.message()};
  robot.ignore_self_collisions();
  return std::unique_ptr<ArmLoop>(
      new ArmLoop(sc, robot, std::move(*model), std::move(*commander), std::move(jtc), std::move(index)));
}

std::vector<std::string> ArmLoop::channels() const {
  std::vector<std::string> out{c_.command_channel, c_.state_channel, c_.result_channel, c_.description_channel,
                               c_.joints_tf_channel};
  if (!c_.map_channel.empty()) out.push_back(c_.map_channel);
  return out;
}

void ArmLoop::attach(Output& out, const WheelOdometry& odometry, const ReceiveCorrections& corrections) {
  out_ = &out;
  odometry_ = &odometry;
  if (auto c = corrections.clocks.find(c_.command_channel); c != corrections.clocks.end()) command_clock_ = c->second;
  if (auto r = corrections.retime.find(c_.command_channel); r != corrections.retime.end()) {
    retime_us_ = r->second.us();
    // A re-timed command starts at its (new) stamp: the controller honours stamps, as ros2_control's does.
    controller::JointTrajectoryOptions o = jtc_.options();
    o.start = "stamp";
    jtc_ = controller::JointTrajectoryController(jtc_.joints(), commander_.chain().limits(), o);
  }
  cmd_stream_ = out.add_stream(c_.command_channel);
  state_stream_ = out.add_stream(c_.state_channel);
  result_stream_ = out.add_stream(c_.result_channel);
  description_stream_ = out.add_stream(c_.description_channel);
  joints_tf_stream_ = out.add_stream(c_.joints_tf_channel);
  if (!c_.map_channel.empty()) map_stream_ = out.add_stream(c_.map_channel);
  out.on_arrival(c_.command_channel, [this](int64_t utime, std::span<const uint8_t> bytes) {
    commands_.push_back({utime, std::vector<uint8_t>(bytes.begin(), bytes.end())});
  });
  const std::vector<std::string>& names = commander_.chain().joint_names();
  out.on_arrival(joint_state_channel_, [this, &names](int64_t, std::span<const uint8_t> bytes) {
    driftlab::joint_state_t m;
    if (!lcmtypes::decode(bytes, m)) return;
    Eigen::VectorXd q(static_cast<Eigen::Index>(names.size()));
    for (size_t i = 0; i < names.size(); ++i) {
      const auto it = std::find(m.name.begin(), m.name.end(), names[i]);
      if (it == m.name.end()) return;
      q[static_cast<Eigen::Index>(i)] = m.position[static_cast<size_t>(it - m.name.begin())];
    }
    last_joint_state_ = std::move(q);
  });
}

Eigen::VectorXd ArmLoop::measured() const {
  const std::vector<JointReading> joints = robot_.joints();
  Eigen::VectorXd q(static_cast<Eigen::Index>(index_.size()));
  for (size_t i = 0; i < index_.size(); ++i)
    q[static_cast<Eigen::Index>(i)] = joints[static_cast<size_t>(index_[i])].position;
  return q;
}

void ArmLoop::publish(int64_t now) {
  const int64_t t = now - start_utime_;
  if (!described_) {
    driftlab::robot_description_t d{};
    d.header.frame_id = robot_.base_link();
    d.urdf = model_.xml();
    out_->publish(description_stream_, d, now, now);
    described_ = true;
  }
  if (t >= due_us(n_cmd_, c_.commander.rate)) {
    ++n_cmd_;
    driftlab::joint_trajectory_t m = commander_.command(now, last_joint_state_);
    out_->publish(cmd_stream_, m, now, now);
  }
  if (t >= due_us(n_tf_, c_.joints_tf_rate)) {  // the robot state publisher
    ++n_tf_;
    driftlab::tf_t tf{};
    tf.header.frame_id = robot_.base_link();
    const std::vector<JointReading> joints = robot_.joints();
    for (const JointReading& j : joints) {
      const kinematics::ModelJoint* mj = model_.joint(j.name);
      if (mj != nullptr) tf.transforms.push_back(transform(mj->parent, mj->child, mj->transform(j.position), now));
    }
    tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
    out_->publish(joints_tf_stream_, tf, now, now);
  }
  if (map_stream_ >= 0 && t >= due_us(n_map_, c_.map_rate)) {  // the localization: map -> odom
    ++n_map_;
    Eigen::Isometry3d odom_base = Eigen::Isometry3d::Identity();
    odom_base.translation() = Eigen::Vector3d(odometry_->x(), odometry_->y(), 0);
    odom_base.linear() = Eigen::AngleAxisd(odometry_->yaw(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Eigen::Isometry3d map_base = robot_.link_pose(robot_.base_link());
    // Planar, as a 2D localization gives it: the base's true x, y and yaw.
    const double yaw = std::atan2(map_base.rotation()(1, 0), map_base.rotation()(0, 0));
    map_base.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    map_base.translation().z() = 0;
    driftlab::tf_t tf{};
    tf.header.frame_id = "map";
    tf.transforms.push_back(transform("map", "odom", map_base * odom_base.inverse(), now));
    tf.ntransforms = 1;
    out_->publish(map_stream_, tf, now, now);
  }
}

void ArmLoop::control(int64_t now, double dt) {
  while (!commands_.empty()) {
    driftlab::joint_trajectory_t m;
    const int64_t arrival = commands_.front().utime;
    if (lcmtypes::decode(commands_.front().bytes, m)) {
      if (command_clock_) m.header.utime = corrected_stamp(*command_clock_, m.header.utime, start_utime_);
      if (retime_us_) m.header.utime = arrival - *retime_us_;
      if (auto r = jtc_.receive(m, Time::from_us(arrival))) out_->publish(result_stream_, *r, now, now);
    }
    commands_.pop_front();
  }
  const Eigen::VectorXd q = measured();
  if (auto r = jtc_.update(Time::from_us(now), q, command_)) out_->publish(result_stream_, *r, now, now);
  const std::vector<kinematics::JointLimits>& limits = commander_.chain().limits();
  for (size_t i = 0; i < index_.size(); ++i) {
    robot_.set_joint_rate(index_[i], command_[static_cast<Eigen::Index>(i)], limits[i].effort, dt);
  }
  if (now - start_utime_ >= due_us(n_state_, c_.controller.state_rate)) {
    ++n_state_;
    driftlab::joint_trajectory_state_t s{};
    s.header.frame_id = robot_.base_link();
    const auto n = static_cast<int32_t>(index_.size());
    s.njoints = n;
    s.joint_names = jtc_.joints();
    auto put = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
    s.desired_positions = put(jtc_.desired_position());
    s.desired_velocities = put(jtc_.desired_velocity());
    s.actual_positions = put(q);
    const std::vector<JointReading> joints = robot_.joints();
    for (int idx : index_) s.actual_velocities.push_back(joints[static_cast<size_t>(idx)].velocity);
    s.commands = put(command_);
    s.following = jtc_.following() ? 1 : 0;
    out_->publish(state_stream_, s, now, now);
  }
}

void ArmLoop::add_static(driftlab::tf_t& tf, int64_t now) const {
  for (const kinematics::ModelJoint& j : model_.joints()) {
    if (!j.moves()) tf.transforms.push_back(transform(j.parent, j.child, j.origin, now));
  }
  tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
}

}  // namespace driftlab::sim
