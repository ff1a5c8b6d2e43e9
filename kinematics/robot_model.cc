#include "kinematics/robot_model.h"

#include <console_bridge/console.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <unordered_map>

#include "core/text_file.h"

namespace driftlab::kinematics {
namespace {

/// urdfdom reports parse errors through console_bridge; this keeps the first error of a parse for our message.
class CaptureErrors : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR && first_.empty()) first_ = text;
  }
  std::string first_;
};

Eigen::Isometry3d to_eigen(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  t.linear() =
      Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  return t;
}

std::string quoted(const std::string& s) { return "'" + s + "'"; }

struct XmlJoint {
  std::string name, parent, child;
  int line = 0;
};

/// The links and joints as written, for the structural checks and the lines of messages. Errors name the line.
Status read_structure(const std::string& xml, const std::string& origin, std::vector<std::string>& links,
                      std::vector<XmlJoint>& joints) {
  if (Status s = check_xml_depth(xml, origin); !s) return s;
  TiXmlDocument doc;
  doc.Parse(xml.c_str());
  if (doc.Error()) {
    return Error{origin + ":" + std::to_string(std::max(doc.ErrorRow(), 1)) + ": malformed XML: " + doc.ErrorDesc()};
  }
  const TiXmlElement* robot = doc.RootElement();
  if (robot == nullptr || std::string(robot->Value()) != "robot") return Error{origin + ":1: no <robot> element"};
  auto at = [&](const TiXmlElement* e) { return origin + ":" + std::to_string(e->Row()) + ": "; };
  std::set<std::string> link_set;
  for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr; e = e->NextSiblingElement("link")) {
    const char* n = e->Attribute("name");
    if (n == nullptr || *n == '\0') return Error{at(e) + "a <link> without a name"};
    if (!link_set.insert(n).second) return Error{at(e) + "link " + quoted(n) + " is defined twice"};
    links.emplace_back(n);
  }
  std::unordered_map<std::string, const XmlJoint*> parent_of;  // child link -> its joint
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr; e = e->NextSiblingElement("joint")) {
    XmlJoint j;
    j.line = e->Row();
    const char* n = e->Attribute("name");
    if (n == nullptr || *n == '\0') return Error{at(e) + "a <joint> without a name"};
    j.name = n;
    const std::string what = at(e) + "joint " + quoted(j.name) + ": ";
    for (const char* tag : {"parent", "child"}) {
      const TiXmlElement* c = e->FirstChildElement(tag);
      const char* link = c != nullptr ? c->Attribute("link") : nullptr;
      if (link == nullptr) return Error{what + "no <" + std::string(tag) + " link=\"...\"/>"};
      if (link_set.count(link) == 0) {
        return Error{what + "its " + tag + " link " + quoted(link) + " does not exist (no <link name=\"" + link +
                     "\">)"};
      }
      (std::string(tag) == "parent" ? j.parent : j.child) = link;
    }
    joints.push_back(std::move(j));
  }
  for (const XmlJoint& j : joints) {
    if (auto [it, fresh] = parent_of.emplace(j.child, &j); !fresh) {
      return Error{origin + ":" + std::to_string(j.line) + ": joint " + quoted(j.name) + ": link " + quoted(j.child) +
                   " already has a parent joint, " + quoted(it->second->name) + " (a URDF is a tree)"};
    }
  }
  // A loop: walking up from a joint's parent link reaches its child link again. Every link has one parent joint at
  // most, so each link is walked up from once (a chain of 60,000 links was walked up from every joint: quadratic):
  // a walk that meets itself found a loop, and the first joint in the file on one is named.
  std::unordered_map<std::string_view, size_t> walked;  // link -> the walk that reached it first (1-based)
  std::unordered_map<std::string_view, bool> on_loop;
  for (size_t w = 0; w < joints.size(); ++w) {
    std::string_view link = joints[w].child;
    while (!walked.count(link)) {
      walked.emplace(link, w + 1);
      const auto up = parent_of.find(std::string(link));
      if (up == parent_of.end()) break;
      link = up->second->parent;
    }
    if (walked.at(link) == w + 1 && parent_of.count(std::string(link))) {
      // This walk came back to a link of its own: the links from there round are a loop.
      std::string_view l = link;
      do {
        on_loop[l] = true;
        l = parent_of.at(std::string(l))->parent;
      } while (l != link);
    }
  }
  for (const XmlJoint& j : joints) {
    if (on_loop.count(j.child)) {
      return Error{origin + ":" + std::to_string(j.line) + ": joint " + quoted(j.name) + " closes a loop: link " +
                   quoted(j.child) + " is an ancestor of its own parent " + quoted(j.parent) + " (a URDF is a tree)"};
    }
  }
  return {};
}

}  // namespace

Status check_xml_depth(std::string_view xml, const std::string& origin) {
  int depth = 0;
  size_t i = 0;
  auto skip_past = [&](std::string_view end) {
    const size_t at = xml.find(end, i);
    i = at == std::string_view::npos ? xml.size() : at + end.size();
  };
  while ((i = xml.find('<', i)) != std::string_view::npos) {
    const size_t open = i++;
    if (xml.substr(open).starts_with("<!--")) {
      skip_past("-->");
    } else if (xml.substr(open).starts_with("<![CDATA[")) {
      skip_past("]]>");
    } else if (i < xml.size() && (xml[i] == '?' || xml[i] == '!')) {
      skip_past(">");
    } else if (i < xml.size() && xml[i] == '/') {
      --depth;
      skip_past(">");
    } else {
      // An element's start tag: its end is the first '>' outside quoted attribute values.
      char quote = 0;
      for (; i < xml.size(); ++i) {
        if (quote != 0) {
          if (xml[i] == quote) quote = 0;
        } else if (xml[i] == '"' || xml[i] == '\'') {
          quote = xml[i];
        } else if (xml[i] == '>') {
          break;
        }
      }
      const bool empty = i < xml.size() && i > open && xml[i - 1] == '/';
      if (i < xml.size()) ++i;
      if (!empty && ++depth > kMaxXmlDepth) {
        const auto line = 1 + std::count(xml.begin(), xml.begin() + static_cast<ptrdiff_t>(open), '\n');
        return Error{origin + ":" + std::to_string(line) + ": XML elements nested more than " +
                     std::to_string(kMaxXmlDepth) + " deep: refused before it is parsed (a URDF nests a few levels)"};
      }
    }
  }
  return {};
}

Eigen::Isometry3d ModelJoint::transform(double q) const {
  switch (type) {
    case JointType::kRevolute:
    case JointType::kContinuous: return origin * Eigen::AngleAxisd(q, axis);
    case JointType::kPrismatic: return origin * Eigen::Translation3d(q * axis);
    default: return origin;
  }
}

Result<RobotModel> RobotModel::parse(const std::string& xml, const std::string& origin) {
  std::vector<std::string> links;
  std::vector<XmlJoint> structure;
  if (Status s = read_structure(xml, origin, links, structure); !s) return s.error();

  urdf::ModelInterfaceSharedPtr model;
  {
    // console_bridge's output handler is process-wide.
    static std::mutex mutex;
    std::lock_guard lock(mutex);
    CaptureErrors capture;
    console_bridge::useOutputHandler(&capture);
    model = urdf::parseURDF(xml);
    console_bridge::restorePreviousOutputHandler();
    if (!model) {
      std::string why = capture.first_.empty() ? "not a valid URDF robot" : capture.first_;
      while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
      return Error{origin + ": " + why};
    }
  }
  RobotModel m;
  m.name_ = model->getName();
  m.origin_ = origin;
  m.xml_ = xml;
  m.links_ = std::move(links);
  m.urdf_ = model;
  if (!model->getRoot()) return Error{origin + ": the URDF has no root link"};
  m.root_ = model->getRoot()->name;
  for (const XmlJoint& x : structure) {
    const urdf::JointConstSharedPtr uj = model->getJoint(x.name);
    if (!uj) return Error{origin + ":" + std::to_string(x.line) + ": joint " + quoted(x.name) + ": not read"};
    ModelJoint j;
    j.name = x.name;
    j.parent = x.parent;
    j.child = x.child;
    j.line = x.line;
    j.origin = to_eigen(uj->parent_to_joint_origin_transform);
    j.axis = Eigen::Vector3d(uj->axis.x, uj->axis.y, uj->axis.z);
    switch (uj->type) {
      case urdf::Joint::FIXED: j.type = JointType::kFixed; break;
      case urdf::Joint::REVOLUTE: j.type = JointType::kRevolute; break;
      case urdf::Joint::CONTINUOUS: j.type = JointType::kContinuous; break;
      case urdf::Joint::PRISMATIC: j.type = JointType::kPrismatic; break;
      default: j.type = JointType::kOther; break;
    }
    if (j.moves()) {
      if (j.axis.norm() < 1e-9) return Error{m.where(j) + ": axis is zero"};
      j.axis.normalize();
    }
    if (uj->limits) {
      j.limits.has_position = j.type == JointType::kRevolute || j.type == JointType::kPrismatic;
      j.limits.lower = uj->limits->lower;
      j.limits.upper = uj->limits->upper;
      j.limits.velocity = uj->limits->velocity;
      j.limits.effort = uj->limits->effort;
      if (j.limits.has_position && !(j.limits.lower < j.limits.upper)) {
        return Error{m.where(j) + ": its limit's lower bound must be below its upper bound"};
      }
    }
    m.joints_.push_back(std::move(j));
  }
  for (size_t i = 0; i < m.joints_.size(); ++i) {
    m.joint_by_name_.emplace(m.joints_[i].name, i);
    m.joint_by_child_.emplace(m.joints_[i].child, i);
  }
  for (size_t i = 0; i < m.links_.size(); ++i) m.link_index_.emplace(m.links_[i], i);
  return m;
}

Result<RobotModel> RobotModel::load(const std::string& path) {
  auto text = read_text_file(path, "URDF file");
  if (!text) return text.error();
  return parse(*text, path);
}

const ModelJoint* RobotModel::joint(std::string_view name) const {
  const auto it = joint_by_name_.find(std::string(name));
  return it == joint_by_name_.end() ? nullptr : &joints_[it->second];
}

const ModelJoint* RobotModel::parent_joint(std::string_view link) const {
  const auto it = joint_by_child_.find(std::string(link));
  return it == joint_by_child_.end() ? nullptr : &joints_[it->second];
}

bool RobotModel::has_link(std::string_view link) const { return link_index_.count(std::string(link)) != 0; }

std::string RobotModel::where(const ModelJoint& joint) const {
  return origin_ + (joint.line > 0 ? ":" + std::to_string(joint.line) : std::string()) + ": joint " +
         quoted(joint.name);
}

Result<std::vector<const ModelJoint*>> RobotModel::path(const std::string& base, const std::string& tip) const {
  for (const std::string& link : {base, tip}) {
    if (!has_link(link)) return Error{origin_ + ": robot " + quoted(name_) + " has no link " + quoted(link)};
  }
  std::vector<const ModelJoint*> out;
  for (std::string link = tip; link != base;) {
    const ModelJoint* j = parent_joint(link);
    if (j == nullptr) {
      return Error{origin_ + ": link " + quoted(tip) + " is not below link " + quoted(base) + " in robot " +
                   quoted(name_)};
    }
    out.push_back(j);
    link = j->parent;
  }
  std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace driftlab::kinematics
