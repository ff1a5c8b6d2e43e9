// A robot from a URDF file (urdfdom), built in a Bullet world: links joined by fixed joints become one rigid body
// (a compound of their box, cylinder and sphere collision shapes, with their combined mass and inertia), and
// continuous and revolute joints become Bullet hinges. A differential-drive base is driven through the motors of
// its two wheel hinges, so the wheels roll, slip and push against obstacles; poses are never teleported.
// Thread-safety: a Robot belongs to the thread that steps its world.
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/result.h"

class btDiscreteDynamicsWorld;

namespace driftlab::sim {

struct DriveOptions {
  std::string left_joint = "left_wheel_joint";    ///< URDF joint of the left drive wheel
  std::string right_joint = "right_wheel_joint";  ///< URDF joint of the right drive wheel
  double max_wheel_torque = 2.5;                  ///< motor torque limit per wheel [N*m]
  double wheel_friction = 1.0;                    ///< friction of the wheels (multiplied with the floor's)
  double body_friction = 0.0;                     ///< friction of every other body (casters slide)
  /// How far the robot's whole weight would compress the base's own floor contacts (its casters) [m] when they and
  /// the wheels stand on more than three points: springs of stiffness weight / deflection, critically damped, so the
  /// drive wheels keep the load. A base on three points, or 0 here: rigid.
  double caster_deflection = 0.01;
};

struct JointReading {
  std::string name;
  double position = 0;  ///< [rad], unwrapped since the start
  double velocity = 0;  ///< [rad/s]
  double effort = 0;    ///< motor torque about the joint axis during the last step [N*m]
};

/// One rotor of a multirotor URDF: a continuous joint on the base link whose axis is the body's z.
struct RotorSpec {
  std::string joint, link;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< joint origin in the base link's frame [m]
  int direction = 1;  ///< +1: axis +z, spins counter-clockwise seen from above; -1: axis -z, clockwise
};

/// What a multirotor URDF says of the vehicle (the flight stack's VehicleModel comes from the same numbers).
struct MultirotorSpec {
  std::string name, base_link;
  double mass = 0;                                    ///< every link together [kg]
  Eigen::Vector3d com = Eigen::Vector3d::Zero();      ///< centre of mass in the base link's frame [m]
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();  ///< about the centre of mass, base link axes [kg*m^2]
  std::vector<RotorSpec> rotors;                      ///< in the order urdfdom lists the base's joints
};

/// Reads a multirotor from URDF text (`origin` names it in errors). Rotors are the continuous joints on the base
/// link. Errors, one line naming the file, line and element: malformed XML or URDF, no rotor joints, a link with
/// zero or negative mass (or none in total), a rotor joint without an <axis>, a rotor axis not along the body z.
Result<MultirotorSpec> read_multirotor(const std::string& urdf_xml, const std::string& origin);
Result<MultirotorSpec> load_multirotor(const std::string& urdf_path);

/// How a multirotor is built in Bullet.
struct MultirotorOptions {
  /// false (default): the rotors are part of the airframe's one rigid body and their spin is the caller's (the
  /// simulator's motor model); true: each rotor is a body of its own on a Bullet hinge, as Gazebo builds it.
  bool rotor_bodies = false;
  double body_friction = 0.5;  ///< of every body (landing legs on the floor)
};

class Robot {
 public:
  /// Parses `urdf_xml` (`origin` names it in errors) and adds the robot to `world`, its base link at
  /// `start` (x, y, yaw), lowered until its lowest collision shape touches the floor z = 0. Errors name the file
  /// and the line, link or joint: malformed XML, missing links, mesh shapes, massless bodies, unsupported joints,
  /// drive joints that are not wheels.
  static Result<std::unique_ptr<Robot>> create(const std::string& urdf_xml, const std::string& origin,
                                               btDiscreteDynamicsWorld& world, const Eigen::Vector3d& start,
                                               const DriveOptions& drive);
  static Result<std::unique_ptr<Robot>> load(const std::string& urdf_path, btDiscreteDynamicsWorld& world,
                                             const Eigen::Vector3d& start, const DriveOptions& drive);
  /// A multirotor (read_multirotor's checks first, errors as there), its base link at `start` (x, y, yaw) on the
  /// floor. It has no drive: the caller applies the rotors' forces (apply_force, apply_torque).
  static Result<std::unique_ptr<Robot>> create_multirotor(const std::string& urdf_xml, const std::string& origin,
                                                          btDiscreteDynamicsWorld& world, const Eigen::Vector3d& start,
                                                          const MultirotorOptions& options);
  static Result<std::unique_ptr<Robot>> load_multirotor(const std::string& urdf_path, btDiscreteDynamicsWorld& world,
                                                        const Eigen::Vector3d& start, const MultirotorOptions& options);
  ~Robot();
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  const std::string& name() const;
  const std::string& base_link() const;
  bool has_link(const std::string& link) const;
  /// The pose of a link in the world (true, from the physics) [m, unit quaternion].
  Eigen::Isometry3d link_pose(const std::string& link) const;
  /// The velocity of a link's origin and the angular velocity of its body, both in the world frame [m/s, rad/s].
  Eigen::Vector3d link_linear_velocity(const std::string& link) const;
  Eigen::Vector3d link_angular_velocity(const std::string& link) const;
  /// The pose of a link in the base link's frame when the link is rigidly attached to the base (static TF);
  /// nullopt when a moving joint lies between them.
  std::optional<Eigen::Isometry3d> fixed_in_base(const std::string& link) const;

  /// Wheel geometry, from the URDF: radius of the drive wheels' collision cylinders or spheres, and the
  /// distance between the wheels along the axle [m].
  double wheel_radius() const;
  double wheel_separation() const;
  /// Motor targets for the drive wheels, as forward rolling rates: positive drives the base forward [rad/s],
  /// for the next physics step of dt [s] (the torque limit becomes an impulse limit per step).
  void set_wheel_rates(double left, double right, double dt);
  /// Forward rolling angle of the drive wheels since the start (what an encoder counts) [rad].
  double left_wheel_angle() const;
  double right_wheel_angle() const;

  /// Every continuous and revolute joint (in URDF order).
  std::vector<JointReading> joints() const;

  /// The index of a continuous or revolute joint in joints(), -1 when the robot has none of that name.
  int joint_index(const std::string& name) const;
  /// Places the links below the named joints at these positions [rad] (unnamed joints at zero), as the robot is
  /// switched on: call once, after create() and before the first step. Errors name an unknown joint.
  Status set_initial_positions(const std::map<std::string, double>& positions);
  /// Drives a joint's motor towards `rate` [rad/s, the URDF axis' sense] with at most `max_torque` [N*m], for the
  /// next physics step of dt [s] (as a velocity command interface: the motor holds the joint against gravity).
  void set_joint_rate(int index, double rate, double max_torque, double dt);
  /// The robot's bodies stop colliding with each other (an arm whose collision shapes only approximate its links
  /// would otherwise hit itself where the real one does not); they still collide with the world.
  void ignore_self_collisions();

  /// Call after each physics step of dt [s]: tracks joint angles through full turns.
  void after_step(double dt);

  /// A multirotor's rotors, mass and inertia as its URDF gives them; nullptr for other robots.
  const MultirotorSpec* multirotor() const;
  /// For the next physics step: a force [N] acting at a point of the link's body, both in the world frame, and a
  /// torque [N*m] on the link's body (Bullet clears both after each step).
  void apply_force(const std::string& link, const Eigen::Vector3d& force, const Eigen::Vector3d& point);
  void apply_torque(const std::string& link, const Eigen::Vector3d& torque);

  struct Impl;  ///< opaque (robot.cc)

 private:
  explicit Robot(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace driftlab::sim
