#include "sim/robot.h"

#include <btBulletDynamicsCommon.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "core/text_file.h"
#include "kinematics/robot_model.h"
#include "lcmtypes/planar.h"

namespace driftlab::sim {
namespace {

Eigen::Isometry3d to_eigen(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  t.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  return t;
}

btTransform to_bt(const Eigen::Isometry3d& t) {
  const Eigen::Quaterniond q(t.rotation());
  return btTransform(btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()), static_cast<btScalar>(q.z()),
                                  static_cast<btScalar>(q.w())),
                     btVector3(static_cast<btScalar>(t.translation().x()), static_cast<btScalar>(t.translation().y()),
                               static_cast<btScalar>(t.translation().z())));
}

Eigen::Isometry3d to_eigen(const btTransform& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  const btMatrix3x3& basis = t.getBasis();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.linear()(r, c) = basis[r][c];
  }
  out.translation() = Eigen::Vector3d(t.getOrigin().x(), t.getOrigin().y(), t.getOrigin().z());
  return out;
}

Eigen::Vector3d to_eigen(const btVector3& v) { return {v.x(), v.y(), v.z()}; }
btVector3 to_bt(const Eigen::Vector3d& v) {
  return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
}

/// Line of the first <tag name="name"> element in the document, for messages; 0 when not found.
int line_of(const TiXmlDocument& doc, const char* tag, const std::string& name) {
  const TiXmlElement* robot = doc.RootElement();
  if (robot == nullptr) return 0;
  for (const TiXmlElement* e = robot->FirstChildElement(tag); e != nullptr; e = e->NextSiblingElement(tag)) {
    const char* n = e->Attribute("name");
    if (n != nullptr && name == n) return e->Row();
  }
  return 0;
}

/// A link's mass, centre and inertia (about its centre) in some frame.
struct InertialPart {
  double m;
  Eigen::Vector3d c;
  Eigen::Matrix3d inertia;
};

/// `in` of a link whose frame is `link_in_frame`.
InertialPart part_of(const urdf::Inertial& in, const Eigen::Isometry3d& link_in_frame) {
  const Eigen::Isometry3d frame = link_in_frame * to_eigen(in.origin);
  Eigen::Matrix3d local;
  local << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  return {in.mass, frame.translation(), frame.rotation() * local * frame.rotation().transpose()};
}

/// The parts together: total mass, centre of mass and inertia about it (parallel axis theorem). Needs mass > 0.
InertialPart combine(const std::vector<InertialPart>& parts) {
  InertialPart all{0, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero()};
  for (const InertialPart& p : parts) {
    all.m += p.m;
    all.c += p.m * p.c;
  }
  all.c /= all.m;
  for (const InertialPart& p : parts) {
    const Eigen::Vector3d d = p.c - all.c;
    all.inertia += p.inertia + p.m * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
  }
  return all;
}

/// A URDF's XML (for line numbers) and its urdfdom model.
struct UrdfDocument {
  std::string origin;
  std::unique_ptr<TiXmlDocument> doc;
  std::shared_ptr<const urdf::ModelInterface> model;
  /// "file:line: tag 'name'" for messages.
  std::string at(const char* tag, const std::string& name) const {
    const int line = line_of(*doc, tag, name);
    return origin + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + tag + " '" + name + "'";
  }
};

Result<UrdfDocument> open_urdf(const std::string& xml, const std::string& origin) {
  // TinyXML parses recursively: elements nested 200,000 deep overflowed the stack.
  if (Status s = kinematics::check_xml_depth(xml, origin); !s) return s.error();
  UrdfDocument u{origin, std::make_unique<TiXmlDocument>(), nullptr};
  u.doc->Parse(xml.c_str());
  if (u.doc->Error()) {
    return Error{origin + ":" + std::to_string(std::max(u.doc->ErrorRow(), 1)) +
                 ": malformed XML: " + u.doc->ErrorDesc()};
  }
  // urdfdom's model, after the checks of the tree's structure (a joint's missing link, two parents, a loop, bad
  // limits) urdfdom would report without the line or miss: one line naming the file, line and element.
  auto checked = kinematics::RobotModel::parse(xml, origin);
  if (!checked) return checked.error();
  u.model = checked->urdf();
  return u;
}

}  // namespace

Result<MultirotorSpec> read_multirotor(const std::string& xml, const std::string& origin) {
  auto u = open_urdf(xml, origin);
  if (!u) return u.error();
  const TiXmlDocument& doc = *u->doc;
  const auto& model = u->model;
  auto at = [&](const char* tag, const std::string& name) { return u->at(tag, name); };
  const urdf::LinkConstSharedPtr root = model->getRoot();
  if (!root) return Error{origin + ": the URDF has no root link"};
  MultirotorSpec spec;
  spec.name = model->getName();
  spec.base_link = root->name;

  // Every link's pose in the base frame at zero joint angles, depth first; mass and inertia summed about the base.
  struct Pending {
    urdf::LinkConstSharedPtr link;
    Eigen::Isometry3d in_base;
  };
  std::vector<InertialPart> parts;  // in the base frame
  std::vector<Pending> stack{{root, Eigen::Isometry3d::Identity()}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.link->inertial) {
      if (!(p.link->inertial->mass > 0)) {
        return Error{at("link", p.link->name) + ": mass must be positive (a rotor or body without mass cannot fly)"};
      }
      parts.push_back(part_of(*p.link->inertial, p.in_base));
    }
    for (const auto& joint : p.link->child_joints) {
      const Eigen::Isometry3d in_base = p.in_base * to_eigen(joint->parent_to_joint_origin_transform);
      stack.push_back({model->getLink(joint->child_link_name), in_base});
      if (joint->type != urdf::Joint::CONTINUOUS || p.link != root) continue;
      // urdfdom gives a joint without <axis> the x axis: a rotor's spin axis must be written out.
      const TiXmlElement* element = nullptr;
      for (const TiXmlElement* e = doc.RootElement()->FirstChildElement("joint"); e != nullptr;
           e = e->NextSiblingElement("joint")) {
        const char* n = e->Attribute("name");
        if (n != nullptr && joint->name == n) element = e;
      }
      if (element == nullptr || element->FirstChildElement("axis") == nullptr) {
        return Error{at("joint", joint->name) + ": a rotor joint needs an <axis> (its spin axis, 0 0 1 or 0 0 -1)"};
      }
      const Eigen::Vector3d axis =
          in_base.rotation() * Eigen::Vector3d(joint->axis.x, joint->axis.y, joint->axis.z).normalized();
      if (std::abs(std::abs(axis.z()) - 1) > 1e-6) {
        return Error{at("joint", joint->name) + ": a rotor's axis must be along the body's z (0 0 1 or 0 0 -1)"};
      }
      spec.rotors.push_back({joint->name, joint->child_link_name, in_base.translation(), axis.z() > 0 ? 1 : -1});
    }
  }
  if (spec.rotors.empty()) {
    return Error{at("link", root->name) + ": no rotor joints (continuous joints on the base link)"};
  }
  if (parts.empty())
    return Error{at("link", root->name) + ": the robot has no mass (give its links <inertial> masses)"};
  const InertialPart all = combine(parts);
  spec.mass = all.m;
  spec.com = all.c;
  spec.inertia = all.inertia;
  return spec;
}

Result<MultirotorSpec> load_multirotor(const std::string& urdf_path) {
  auto text = read_text_file(urdf_path, "URDF file");
  if (!text) return text.error();
  return read_multirotor(*text, urdf_path);
}

struct Robot::Impl {
  struct Group {
    std::string root_link;
    Eigen::Isometry3d com_in_root = Eigen::Isometry3d::Identity();  // principal inertia frame in the root link frame
    Eigen::Isometry3d root_in_com = Eigen::Isometry3d::Identity();  // its inverse
    std::unique_ptr<btCompoundShape> shape;
    std::vector<std::unique_ptr<btCollisionShape>> children;
    std::unique_ptr<btDefaultMotionState> motion;
    std::unique_ptr<btRigidBody> body;
    Eigen::Isometry3d root_pose() const { return to_eigen(body->getWorldTransform()) * root_in_com; }
  };
  struct LinkInfo {
    int group = 0;
    Eigen::Isometry3d in_group = Eigen::Isometry3d::Identity();  // link frame in its group's root link frame
  };
  struct Joint {
    std::string name;
    int parent_group = 0, child_group = 0;
    Eigen::Isometry3d origin_in_parent_root = Eigen::Isometry3d::Identity();  // joint frame in the parent group's root
    Eigen::Vector3d axis = Eigen::Vector3d::UnitX();                         // unit, in the joint frame
    std::unique_ptr<btHingeConstraint> hinge;
    btJointFeedback feedback;
    double angle = 0;     // unwrapped [rad]
    double raw = 0;       // last wrapped reading [rad]
    double velocity = 0;  // [rad/s]
  };

  btDiscreteDynamicsWorld* world = nullptr;
  std::string name;
  std::vector<Group> groups;  // groups[0] holds the base link
  std::map<std::string, LinkInfo> links;
  std::vector<Joint> joints;
  std::optional<MultirotorSpec> multirotor;
  int left = -1, right = -1;  // drive joints
  double left_forward = 1, right_forward = 1;  // joint rate per forward rolling rate
  double wheel_radius = 0, wheel_separation = 0;
  double max_wheel_torque = 0;  // [N*m]

  ~Impl() {
    for (auto& j : joints) {
      if (j.hinge) world->removeConstraint(j.hinge.get());
    }
    for (auto& g : groups) {
      if (g.body) world->removeRigidBody(g.body.get());
    }
  }

  /// Angle of the child group about the joint axis relative to its zero position [rad, wrapped].
  double measure(const Joint& j) const {
    const Eigen::Isometry3d joint_world = groups[j.parent_group].root_pose() * j.origin_in_parent_root;
    const Eigen::Matrix3d rel = joint_world.rotation().transpose() * groups[j.child_group].root_pose().rotation();
    Eigen::Vector3d u = j.axis.unitOrthogonal();
    const Eigen::Vector3d v = rel * u;
    return std::atan2(u.cross(v).dot(j.axis), u.dot(v));
  }
  double rate(const Joint& j) const {
    const Eigen::Vector3d axis_world =
        (groups[j.parent_group].root_pose() * j.origin_in_parent_root).rotation() * j.axis;
    const Eigen::Vector3d wa = to_eigen(groups[j.parent_group].body->getAngularVelocity());
    const Eigen::Vector3d wb = to_eigen(groups[j.child_group].body->getAngularVelocity());
    return (wb - wa).dot(axis_world);
  }
};

Robot::Robot(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Robot::~Robot() = default;

Result<std::unique_ptr<Robot>> Robot::load(const std::string& urdf_path, btDiscreteDynamicsWorld& world,
                                           const Eigen::Vector3d& start, const DriveOptions& drive) {
  auto text = read_text_file(urdf_path, "URDF file");
  if (!text) return text.error();
  return create(*text, urdf_path, world, start, drive);
}

namespace {

/// The robot's bodies in `world` from an opened URDF: links joined by fixed joints (and, with `rotors_fixed`, the
/// continuous joints on the root link: a multirotor's rotors) become one body each, the other continuous and
/// revolute joints hinges. Bodies get `friction`.
Result<std::unique_ptr<Robot::Impl>> build_bodies(const UrdfDocument& u, btDiscreteDynamicsWorld& world,
                                                  const Eigen::Vector3d& start, double friction, bool rotors_fixed);

}  // namespace

Result<std::unique_ptr<Robot>> Robot::create(const std::string& xml, const std::string& origin,
                                             btDiscreteDynamicsWorld& world, const Eigen::Vector3d& start,
                                             const DriveOptions& drive) {
  auto u = open_urdf(xml, origin);
  if (!u) return u.error();
  auto at = [&](const char* tag, const std::string& name) { return u->at(tag, name); };
  const auto model = u->model;
  auto built = build_bodies(*u, world, start, drive.body_friction, false);
  if (!built) return built.error();
  std::unique_ptr<Impl> impl = std::move(*built);

  // The drive.
  auto find_joint = [&](const std::string& name) -> int {
    for (std::size_t i = 0; i < impl->joints.size(); ++i) {
      if (impl->joints[i].name == name) return static_cast<int>(i);
    }
    return -1;
  };
  impl->left = find_joint(drive.left_joint);
  impl->right = find_joint(drive.right_joint);
  for (const auto& [idx, jname] :
       {std::pair{impl->left, drive.left_joint}, std::pair{impl->right, drive.right_joint}}) {
    if (idx < 0) {
      return Error{origin + ": drive joint '" + jname + "' is not a continuous or revolute joint of robot '" +
                   impl->name + "'"};
    }
  }
  double radius[2] = {0, 0};
  Eigen::Vector3d axle_point[2];
  for (int side = 0; side < 2; ++side) {
    Impl::Joint& j = impl->joints[side == 0 ? impl->left : impl->right];
    if (j.parent_group != 0) return Error{at("joint", j.name) + ": a drive wheel must be attached to the base"};
    const Impl::Group& wheel = impl->groups[j.child_group];
    for (const auto& c : model->getLink(wheel.root_link)->collision_array) {
      if (c->geometry && c->geometry->type == urdf::Geometry::CYLINDER) {
        radius[side] = static_cast<const urdf::Cylinder&>(*c->geometry).radius;
      } else if (c->geometry && c->geometry->type == urdf::Geometry::SPHERE) {
        radius[side] = static_cast<const urdf::Sphere&>(*c->geometry).radius;
      }
    }
    if (radius[side] <= 0)
      return Error{at("link", wheel.root_link) + ": a drive wheel needs a cylinder or sphere collision"};
    // Rolling forward (+x of the base) with the contact point below the axle: which sign of the joint rate?
    const Eigen::Vector3d axis_base = j.origin_in_parent_root.rotation() * j.axis;
    // The contact point moves against the rolling direction: forward rolling is -(w x r_contact).x per unit rate.
    const double forward = -axis_base.cross(Eigen::Vector3d(0, 0, -radius[side])).x();
    if (std::abs(forward) < 1e-6 * radius[side]) {
      return Error{at("joint", j.name) + ": a drive wheel's axis must be horizontal and across the base"};
    }
    (side == 0 ? impl->left_forward : impl->right_forward) = forward > 0 ? 1.0 : -1.0;
    axle_point[side] = j.origin_in_parent_root.translation();
    Impl::Group& wheel_group = impl->groups[j.child_group];
    wheel_group.body->setFriction(static_cast<btScalar>(drive.wheel_friction));
    // A drive wheel touches the floor at one point below its axle, like the centre of a tyre's contact patch: a
    // sphere of the wheel's radius stands in for its cylinder. (A rigid cylinder touches at its two rims, and the
    // small camber that Bullet's hinge allows under load then shifts the effective track by a few percent.)
    for (int i = wheel_group.shape->getNumChildShapes() - 1; i >= 0; --i) {
      if (wheel_group.shape->getChildShape(i)->getShapeType() != CYLINDER_SHAPE_PROXYTYPE) continue;
      const btTransform t = wheel_group.shape->getChildTransform(i);
      auto sphere = std::make_unique<btSphereShape>(static_cast<btScalar>(radius[side]));
      wheel_group.shape->removeChildShapeByIndex(i);
      wheel_group.shape->addChildShape(t, sphere.get());
      wheel_group.children.push_back(std::move(sphere));
    }
    world.updateSingleAabb(wheel_group.body.get());
  }
  impl->max_wheel_torque = drive.max_wheel_torque;
  impl->wheel_radius = 0.5 * (radius[0] + radius[1]);
  impl->wheel_separation = std::abs(axle_point[0].y() - axle_point[1].y());
  if (impl->wheel_separation <= 0) return Error{origin + ": the drive wheels sit at the same y: no separation"};
  // The base's own contacts with the floor (its casters) on a suspension when they over-determine the support. A
  // base on two drive wheels and one caster stands on three points, and statics decides what each carries. On two
  // wheels and two casters (or a skid, a flat face) it stands on four or more: rigid contacts leave the load sharing
  // to Bullet's iterative solver, which loads the contacts of the heavy base body and unloads the wheels, whose
  // contacts reach the base only through their light bodies and hinges. The wheels then lose their grip and the base
  // slides on its low-friction casters under the least reaction force (an arm's, a turn's) while the wheel odometry
  // says it drives straight. Real bases spring their casters (or their wheels) for the same reason: here a caster
  // contact is a spring, critically damped, that the robot's whole weight would compress by `caster_deflection`, so
  // it carries only its spring's share and the drive wheels keep the rest.
  if (drive.caster_deflection > 0) {
    auto lowest_points = [](const Impl::Group& g, auto&& visit) {
      const btTransform body = g.body->getWorldTransform();
      for (int i = 0; i < g.shape->getNumChildShapes(); ++i) {
        btVector3 lo, hi;
        g.shape->getChildShape(i)->getAabb(body * g.shape->getChildTransform(i), lo, hi);
        visit(g.shape->getChildShape(i)->getShapeType(), static_cast<double>(lo.z()));
      }
    };
    double floor_z = INFINITY;
    for (const int joint : {impl->left, impl->right}) {
      lowest_points(impl->groups[impl->joints[joint].child_group],
                    [&](int, double z) { floor_z = std::min(floor_z, z); });
    }
    int points = 2;  // the wheels'
    lowest_points(impl->groups[0], [&](int type, double z) {
      if (z < floor_z + drive.caster_deflection) points += type == SPHERE_SHAPE_PROXYTYPE ? 1 : 3;  // a ball, a face
    });
    if (points > 3) {
      double mass = 0;
      for (const auto& g : impl->groups) mass += 1.0 / static_cast<double>(g.body->getInvMass());
      const double weight = mass * static_cast<double>(-world.getGravity().z());
      const double stiffness = weight / drive.caster_deflection;  // [N/m]
      const double damping = 2.0 * std::sqrt(stiffness * mass);   // [N*s/m], critical for the whole robot
      impl->groups[0].body->setContactStiffnessAndDamping(static_cast<btScalar>(stiffness),
                                                          static_cast<btScalar>(damping));
    }
  }
  return std::unique_ptr<Robot>(new Robot(std::move(impl)));
}

Result<std::unique_ptr<Robot>> Robot::create_multirotor(const std::string& xml, const std::string& origin,
                                                        btDiscreteDynamicsWorld& world, const Eigen::Vector3d& start,
                                                        const MultirotorOptions& options) {
  auto spec = read_multirotor(xml, origin);
  if (!spec) return spec.error();
  auto u = open_urdf(xml, origin);
  if (!u) return u.error();
  auto built = build_bodies(*u, world, start, options.body_friction, !options.rotor_bodies);
  if (!built) return built.error();
  std::unique_ptr<Impl> impl = std::move(*built);
  impl->multirotor = std::move(*spec);
  return std::unique_ptr<Robot>(new Robot(std::move(impl)));
}

Result<std::unique_ptr<Robot>> Robot::load_multirotor(const std::string& urdf_path, btDiscreteDynamicsWorld& world,
                                                      const Eigen::Vector3d& start, const MultirotorOptions& options) {
  auto text = read_text_file(urdf_path, "URDF file");
  if (!text) return text.error();
  return create_multirotor(*text, urdf_path, world, start, options);
}

namespace {

Result<std::unique_ptr<Robot::Impl>> build_bodies(const UrdfDocument& u, btDiscreteDynamicsWorld& world,
                                                  const Eigen::Vector3d& start, double friction, bool rotors_fixed) {
  using Impl = Robot::Impl;
  const std::string& origin = u.origin;
  auto at = [&](const char* tag, const std::string& name) { return u.at(tag, name); };
  const auto model = u.model;

  auto impl = std::make_unique<Impl>();
  impl->world = &world;
  impl->name = model->getName();
  const urdf::LinkConstSharedPtr root = model->getRoot();
  if (!root) return Error{origin + ": the URDF has no root link"};

  // Group links joined by fixed joints, depth first from the root; record each moving joint.
  struct Pending {
    urdf::LinkConstSharedPtr link;
    int group;
    Eigen::Isometry3d in_group;
  };
  std::vector<Pending> stack{{root, 0, Eigen::Isometry3d::Identity()}};
  impl->groups.emplace_back();
  impl->groups[0].root_link = root->name;
  std::vector<urdf::JointConstSharedPtr> moving;
  std::vector<std::pair<int, Eigen::Isometry3d>> moving_parent;  // parent group, joint origin in that group's root
  while (!stack.empty()) {
    Pending p = stack.back();
    stack.pop_back();
    impl->links[p.link->name] = {p.group, p.in_group};
    for (const auto& joint : p.link->child_joints) {
      const urdf::LinkConstSharedPtr child = model->getLink(joint->child_link_name);
      const Eigen::Isometry3d origin_in_group = p.in_group * to_eigen(joint->parent_to_joint_origin_transform);
      switch (joint->type) {
        case urdf::Joint::FIXED:
          stack.push_back({child, p.group, origin_in_group});
          break;
        case urdf::Joint::CONTINUOUS:
          if (rotors_fixed && p.link == root) {  // a rotor: part of the airframe's body, its spin kept apart
            stack.push_back({child, p.group, origin_in_group});
            break;
          }
          [[fallthrough]];
        case urdf::Joint::REVOLUTE: {
          const int g = static_cast<int>(impl->groups.size());
          impl->groups.emplace_back();
          impl->groups[g].root_link = child->name;
          moving.push_back(joint);
          moving_parent.emplace_back(p.group, origin_in_group);
          stack.push_back({child, g, Eigen::Isometry3d::Identity()});
          break;
        }
        default:
          return Error{at("joint", joint->name) +
                       ": only fixed, continuous and revolute joints are supported (this one is prismatic, planar or "
                       "floating)"};
      }
    }
  }

  // Shapes, mass and inertia per group.
  // Group root poses in the base frame at zero joint angles (groups are created parent first).
  std::vector<Eigen::Isometry3d> group_in_base(impl->groups.size(), Eigen::Isometry3d::Identity());
  for (std::size_t j = 0; j < moving.size(); ++j) {
    group_in_base[j + 1] = group_in_base[moving_parent[j].first] * moving_parent[j].second;
  }
  double lowest = INFINITY;
  for (std::size_t gi = 0; gi < impl->groups.size(); ++gi) {
    Impl::Group& g = impl->groups[gi];
    double mass = 0;
    std::vector<InertialPart> parts;  // in the group root frame
    struct ShapeAt {
      std::unique_ptr<btCollisionShape> shape;
      Eigen::Isometry3d pose;  // in the group root frame
    };
    std::vector<ShapeAt> shapes;
    for (const auto& [link_name, info] : impl->links) {
      if (info.group != static_cast<int>(gi)) continue;
      const urdf::LinkConstSharedPtr link = model->getLink(link_name);
      if (link->inertial && link->inertial->mass > 0) {
        parts.push_back(part_of(*link->inertial, info.in_group));
        mass += link->inertial->mass;
      } else if (link->inertial && link->inertial->mass < 0) {
        return Error{at("link", link_name) + ": negative mass"};
      }
      for (const auto& collision : link->collision_array) {
        if (!collision->geometry) continue;
        const Eigen::Isometry3d pose = info.in_group * to_eigen(collision->origin);
        std::unique_ptr<btCollisionShape> shape;
        const Eigen::Isometry3d in_base = group_in_base[gi] * pose;
        switch (collision->geometry->type) {
          case urdf::Geometry::BOX: {
            const auto& b = static_cast<const urdf::Box&>(*collision->geometry);
            if (!(b.dim.x > 0 && b.dim.y > 0 && b.dim.z > 0)) return Error{at("link", link_name) + ": box size must be positive"};
            shape = std::make_unique<btBoxShape>(btVector3(b.dim.x / 2, b.dim.y / 2, b.dim.z / 2));
            for (int c = 0; c < 8; ++c) {
              const Eigen::Vector3d corner((c & 1 ? 0.5 : -0.5) * b.dim.x, (c & 2 ? 0.5 : -0.5) * b.dim.y,
                                           (c & 4 ? 0.5 : -0.5) * b.dim.z);
              lowest = std::min(lowest, (in_base * corner).z());
            }
            break;
          }
          case urdf::Geometry::CYLINDER: {
            const auto& c = static_cast<const urdf::Cylinder&>(*collision->geometry);
            if (!(c.radius > 0 && c.length > 0)) return Error{at("link", link_name) + ": cylinder radius and length must be positive"};
            shape = std::make_unique<btCylinderShapeZ>(btVector3(c.radius, c.radius, c.length / 2));
            // Lowest point of the cylinder: its axis end minus the radius across the axis.
            const Eigen::Vector3d axis = in_base.rotation().col(2);
            const double across = c.radius * std::sqrt(std::max(0.0, 1 - axis.z() * axis.z()));
            lowest = std::min(lowest, in_base.translation().z() - std::abs(axis.z()) * c.length / 2 - across);
            break;
          }
          case urdf::Geometry::SPHERE: {
            const auto& s = static_cast<const urdf::Sphere&>(*collision->geometry);
            if (!(s.radius > 0)) return Error{at("link", link_name) + ": sphere radius must be positive"};
            shape = std::make_unique<btSphereShape>(s.radius);
            lowest = std::min(lowest, in_base.translation().z() - s.radius);
            break;
          }
          default:
            return Error{at("link", link_name) +
                         ": mesh collision geometry is not supported (use box, cylinder or sphere shapes)"};
        }
        shapes.push_back({std::move(shape), pose});
      }
    }
    if (mass <= 0) {
      return Error{at("link", g.root_link) + ": has no mass (give it, or a link fixed to it, an <inertial> with mass > 0)"};
    }
    if (shapes.empty()) {
      return Error{at("link", g.root_link) + ": has no collision shape (it, or a link fixed to it, needs a <collision>)"};
    }
    const InertialPart all = combine(parts);
    const Eigen::Vector3d& com = all.c;
    const Eigen::Matrix3d& inertia = all.inertia;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(inertia);
    Eigen::Matrix3d axes = eig.eigenvectors();
    if (axes.determinant() < 0) axes.col(2) = -axes.col(2);
    Eigen::Vector3d principal = eig.eigenvalues().cwiseMax(1e-6 * mass);
    g.com_in_root.linear() = axes;
    g.com_in_root.translation() = com;
    g.root_in_com = g.com_in_root.inverse();

    g.shape = std::make_unique<btCompoundShape>();
    for (ShapeAt& s : shapes) {
      g.shape->addChildShape(to_bt(g.root_in_com * s.pose), s.shape.get());
      g.children.push_back(std::move(s.shape));
    }
    g.motion = std::make_unique<btDefaultMotionState>();
    btRigidBody::btRigidBodyConstructionInfo ci(static_cast<btScalar>(mass), g.motion.get(), g.shape.get(),
                                                to_bt(principal));
    g.body = std::make_unique<btRigidBody>(ci);
    g.body->setActivationState(DISABLE_DEACTIVATION);
    g.body->setFriction(static_cast<btScalar>(friction));
  }

  // Place the base: start x, y, yaw, lowered onto the floor.
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  base.linear() = Eigen::AngleAxisd(start.z(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  base.translation() = Eigen::Vector3d(start.x(), start.y(), -lowest + 1e-3);
  for (std::size_t gi = 0; gi < impl->groups.size(); ++gi) {
    Impl::Group& g = impl->groups[gi];
    g.body->setWorldTransform(to_bt(base * group_in_base[gi] * g.com_in_root));
    g.motion->setWorldTransform(g.body->getWorldTransform());
    world.addRigidBody(g.body.get());
  }

  // Hinges.
  for (std::size_t k = 0; k < moving.size(); ++k) {
    const urdf::Joint& uj = *moving[k];
    Impl::Joint j;
    j.name = uj.name;
    j.parent_group = moving_parent[k].first;
    j.child_group = static_cast<int>(k + 1);
    j.origin_in_parent_root = moving_parent[k].second;
    j.axis = Eigen::Vector3d(uj.axis.x, uj.axis.y, uj.axis.z);
    if (j.axis.norm() < 1e-9) return Error{at("joint", uj.name) + ": axis is zero"};
    j.axis.normalize();
    const Impl::Group& pa = impl->groups[j.parent_group];
    const Impl::Group& ch = impl->groups[j.child_group];
    const Eigen::Isometry3d joint_in_pa = pa.root_in_com * j.origin_in_parent_root;
    const Eigen::Isometry3d joint_in_ch = ch.root_in_com;  // the child root is the joint frame
    j.hinge = std::make_unique<btHingeConstraint>(*pa.body, *ch.body, to_bt(Eigen::Vector3d(joint_in_pa.translation())),
                                                  to_bt(Eigen::Vector3d(joint_in_ch.translation())),
                                                  to_bt(Eigen::Vector3d(joint_in_pa.rotation() * j.axis)),
                                                  to_bt(Eigen::Vector3d(joint_in_ch.rotation() * j.axis)));
    if (uj.type == urdf::Joint::REVOLUTE && uj.limits) {
      // Bullet measures a hinge's angle from the bodies' poses when it was made (here: the URDF's zero), and in
      // its own sense about the axis: find both from the angle now and with the child turned a little by the URDF
      // axis, and give Bullet the URDF's range in its terms (Bullet's limit takes a span of up to 2 pi).
      const btTransform ta = pa.body->getCenterOfMassTransform(), tb = ch.body->getCenterOfMassTransform();
      const Eigen::Vector3d axis_world = to_eigen(ta).rotation() * joint_in_pa.rotation() * j.axis;
      btTransform turned = tb;
      turned.setBasis(btMatrix3x3(btQuaternion(to_bt(axis_world), btScalar(0.01))) * tb.getBasis());
      const double zero = j.hinge->getHingeAngle(ta, tb);
      const double sense = j.hinge->getHingeAngle(ta, turned) - zero > 0 ? 1.0 : -1.0;
      const double a = zero + sense * uj.limits->lower, b = zero + sense * uj.limits->upper;
      j.hinge->setLimit(static_cast<btScalar>(std::min(a, b)), static_cast<btScalar>(std::max(a, b)));
    }
    impl->joints.push_back(std::move(j));
  }
  for (auto& j : impl->joints) {
    // Bullet fills the feedback only when it solves a step: zero it for readings before the first one.
    j.feedback.m_appliedForceBodyA.setZero();
    j.feedback.m_appliedTorqueBodyA.setZero();
    j.feedback.m_appliedForceBodyB.setZero();
    j.feedback.m_appliedTorqueBodyB.setZero();
    j.hinge->setJointFeedback(&j.feedback);
    world.addConstraint(j.hinge.get(), /*disableCollisionsBetweenLinkedBodies=*/true);
  }

  return impl;
}

}  // namespace

const std::string& Robot::name() const { return impl_->name; }
const std::string& Robot::base_link() const { return impl_->groups[0].root_link; }
bool Robot::has_link(const std::string& link) const { return impl_->links.count(link) > 0; }

Eigen::Isometry3d Robot::link_pose(const std::string& link) const {
  const Impl::LinkInfo& info = impl_->links.at(link);
  return impl_->groups[info.group].root_pose() * info.in_group;
}

Eigen::Vector3d Robot::link_linear_velocity(const std::string& link) const {
  const Impl::LinkInfo& info = impl_->links.at(link);
  const btRigidBody& body = *impl_->groups[info.group].body;
  const Eigen::Vector3d rel = link_pose(link).translation() - to_eigen(body.getCenterOfMassPosition());
  return to_eigen(body.getVelocityInLocalPoint(to_bt(rel)));
}

Eigen::Vector3d Robot::link_angular_velocity(const std::string& link) const {
  return to_eigen(impl_->groups[impl_->links.at(link).group].body->getAngularVelocity());
}

std::optional<Eigen::Isometry3d> Robot::fixed_in_base(const std::string& link) const {
  const Impl::LinkInfo& info = impl_->links.at(link);
  if (info.group != 0) return std::nullopt;
  return impl_->links.at(base_link()).in_group.inverse() * info.in_group;
}

double Robot::wheel_radius() const { return impl_->wheel_radius; }
double Robot::wheel_separation() const { return impl_->wheel_separation; }

void Robot::set_wheel_rates(double left, double right, double dt) {
  // Bullet's hinge motor target is the rate of the parent relative to the child about the axis (the opposite
  // of the URDF's sign convention, checked in tests/sim/robot_test.cc); its limit is an impulse per step.
  const auto impulse = static_cast<btScalar>(impl_->max_wheel_torque * dt);
  impl_->joints[impl_->left].hinge->enableAngularMotor(true, static_cast<btScalar>(-left * impl_->left_forward), impulse);
  impl_->joints[impl_->right].hinge->enableAngularMotor(true, static_cast<btScalar>(-right * impl_->right_forward),
                                                        impulse);
}

double Robot::left_wheel_angle() const { return impl_->joints[impl_->left].angle * impl_->left_forward; }
double Robot::right_wheel_angle() const { return impl_->joints[impl_->right].angle * impl_->right_forward; }

std::vector<JointReading> Robot::joints() const {
  std::vector<JointReading> out;
  out.reserve(impl_->joints.size());
  for (const Impl::Joint& j : impl_->joints) {
    const Eigen::Vector3d axis_world =
        (impl_->groups[j.parent_group].root_pose() * j.origin_in_parent_root).rotation() * j.axis;
    // The torque the constraint applied to the child about the joint axis (the motor's, as the hinge's other
    // axes are locked and carry none about this one).
    const double effort = to_eigen(j.feedback.m_appliedTorqueBodyB).dot(axis_world);
    out.push_back({j.name, j.angle, j.velocity, effort});
  }
  return out;
}

int Robot::joint_index(const std::string& name) const {
  for (std::size_t i = 0; i < impl_->joints.size(); ++i) {
    if (impl_->joints[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

Status Robot::set_initial_positions(const std::map<std::string, double>& positions) {
  std::vector<double> q(impl_->joints.size(), 0.0);
  for (const auto& [name, value] : positions) {
    const int i = joint_index(name);
    if (i < 0) return Error{"robot '" + impl_->name + "' has no continuous or revolute joint '" + name + "'"};
    q[static_cast<std::size_t>(i)] = value;
  }
  // Groups are created parent first, one per moving joint (group k + 1 below joint k).
  std::vector<Eigen::Isometry3d> root(impl_->groups.size());
  root[0] = impl_->groups[0].root_pose();
  for (std::size_t k = 0; k < impl_->joints.size(); ++k) {
    Impl::Joint& j = impl_->joints[k];
    root[static_cast<std::size_t>(j.child_group)] =
        root[static_cast<std::size_t>(j.parent_group)] * j.origin_in_parent_root * Eigen::AngleAxisd(q[k], j.axis);
    Impl::Group& g = impl_->groups[static_cast<std::size_t>(j.child_group)];
    g.body->setWorldTransform(to_bt(root[static_cast<std::size_t>(j.child_group)] * g.com_in_root));
    g.body->setLinearVelocity(btVector3(0, 0, 0));
    g.body->setAngularVelocity(btVector3(0, 0, 0));
    g.motion->setWorldTransform(g.body->getWorldTransform());
    impl_->world->updateSingleAabb(g.body.get());
    j.raw = wrap_angle(q[k]);
    j.angle = q[k];
    j.velocity = 0;
  }
  return {};
}

void Robot::set_joint_rate(int index, double rate, double max_torque, double dt) {
  // Bullet's hinge motor target is the rate of the parent relative to the child (see set_wheel_rates).
  impl_->joints[static_cast<std::size_t>(index)].hinge->enableAngularMotor(true, static_cast<btScalar>(-rate),
                                                                           static_cast<btScalar>(max_torque * dt));
}

void Robot::ignore_self_collisions() {
  for (auto& a : impl_->groups) {
    for (auto& b : impl_->groups) {
      if (&a != &b) a.body->setIgnoreCollisionCheck(b.body.get(), true);
    }
  }
}

const MultirotorSpec* Robot::multirotor() const { return impl_->multirotor ? &*impl_->multirotor : nullptr; }

void Robot::apply_force(const std::string& link, const Eigen::Vector3d& force, const Eigen::Vector3d& point) {
  btRigidBody& body = *impl_->groups[impl_->links.at(link).group].body;
  body.applyForce(to_bt(force), to_bt(Eigen::Vector3d(point - to_eigen(body.getCenterOfMassPosition()))));
}

void Robot::apply_torque(const std::string& link, const Eigen::Vector3d& torque) {
  impl_->groups[impl_->links.at(link).group].body->applyTorque(to_bt(torque));
}

void Robot::after_step(double dt) {
  for (Impl::Joint& j : impl_->joints) {
    const double raw = impl_->measure(j);
    j.angle += wrap_angle(raw - j.raw);
    j.raw = raw;
    j.velocity = impl_->rate(j);
  }
}

}  // namespace driftlab::sim
