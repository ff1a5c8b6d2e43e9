// A robot's kinematic tree from its URDF (parsed by urdfdom), shared by the simulator, the controllers and the
// analyzers: every joint with its origin, axis, type and limits, and the line it is on, so a problem is reported as
// one line naming the file and the element. Structural problems urdfdom reports vaguely or not at all are checked
// first: a joint whose parent or child link does not exist, a link with two parent joints, a loop of joints.
// The transform of each joint at a position is what robot_state_publisher publishes on TF.
// Thread-safety: immutable after parse(); share freely.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "core/result.h"

namespace urdf {
class ModelInterface;
}

namespace driftlab::kinematics {

enum class JointType { kFixed, kRevolute, kContinuous, kPrismatic, kOther };

struct JointLimits {
  bool has_position = false;    ///< lower/upper hold (revolute, prismatic)
  double lower = 0, upper = 0;  ///< [rad] or [m]
  double velocity = 0;          ///< [rad/s] or [m/s]; 0: none given
  double effort = 0;            ///< [N*m] or [N]; 0: none given
};

struct ModelJoint {
  std::string name, parent, child;  ///< the joint and its parent and child links
  JointType type = JointType::kFixed;
  Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();  ///< the joint frame in the parent link's frame
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();           ///< unit, in the joint frame
  JointLimits limits;
  int line = 0;  ///< in the URDF file; 0 when unknown

  bool moves() const { return type != JointType::kFixed; }
  /// The child link's pose in the parent link's frame at joint position q [rad or m].
  Eigen::Isometry3d transform(double q) const;
};

/// How deep XML elements may nest in a URDF: TinyXML parses recursively, and 200,000 nested elements overflowed
/// the stack. A URDF nests a few levels deep.
constexpr int kMaxXmlDepth = 1000;

/// Scans XML text for its elements' nesting, without parsing it; an error ("FILE:LINE: XML elements nested more
/// than 1000 deep: refused before it is parsed") when it goes past kMaxXmlDepth. Call before TinyXML sees it.
Status check_xml_depth(std::string_view xml, const std::string& origin);

class RobotModel {
 public:
  /// Parses URDF text; `origin` names it in errors ("FILE:LINE: joint 'NAME': ...").
  static Result<RobotModel> parse(const std::string& xml, const std::string& origin);
  static Result<RobotModel> load(const std::string& path);

  const std::string& name() const { return name_; }
  const std::string& origin() const { return origin_; }
  const std::string& root() const { return root_; }
  const std::string& xml() const { return xml_; }
  /// urdfdom's model of the same file (links with their inertias and shapes, for the simulator).
  const std::shared_ptr<const urdf::ModelInterface>& urdf() const { return urdf_; }
  /// Every joint, in the order of the file.
  const std::vector<ModelJoint>& joints() const { return joints_; }
  const ModelJoint* joint(std::string_view name) const;
  /// The joint whose child is `link`; nullptr for the root (or an unknown link).
  const ModelJoint* parent_joint(std::string_view link) const;
  bool has_link(std::string_view link) const;
  /// "FILE:LINE: joint 'NAME'", for messages.
  std::string where(const ModelJoint& joint) const;
  /// The joints from link `base` down to link `tip`, base first. An error when tip is not below base.
  Result<std::vector<const ModelJoint*>> path(const std::string& base, const std::string& tip) const;
  /// The pose of `link` in the frame of `base` (an ancestor) at the positions `position(joint name)` gives.
  template <typename PositionOf>
  Eigen::Isometry3d pose_in(const std::string& base, const std::string& link, PositionOf&& position) const {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    if (link == base) return pose;
    for (const ModelJoint* j = parent_joint(link); j != nullptr; j = parent_joint(j->parent)) {
      pose = j->transform(j->moves() ? position(j->name) : 0.0) * pose;
      if (j->parent == base) break;
    }
    return pose;
  }

 private:
  std::string name_, origin_, root_, xml_;
  std::vector<ModelJoint> joints_;
  std::vector<std::string> links_;
  // Indexes into joints_ and links_ (a chain of 60,000 links walked joints_ for each of its links: quadratic).
  std::unordered_map<std::string, size_t> joint_by_name_, joint_by_child_, link_index_;
  std::shared_ptr<const urdf::ModelInterface> urdf_;
};

}  // namespace driftlab::kinematics
