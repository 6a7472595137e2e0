#include "ropes_sim/robot_model.hpp"

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include <cstdio>
#include <fstream>
#include <mutex>
#include <queue>
#include <set>
#include <sstream>

namespace ropes::sim {

namespace {

Eigen::Isometry3d to_isometry(const urdf::Pose& pose) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() =
      Eigen::Quaterniond(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z)
          .normalized()
          .toRotationMatrix();
  X.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return X;
}

Visual to_visual(const urdf::Visual& v, const std::string& source, const std::string& link) {
  Visual out;
  out.X_LV = to_isometry(v.origin);
  if (v.material) {
    out.rgba = Eigen::Vector4d(v.material->color.r, v.material->color.g, v.material->color.b,
                               v.material->color.a);
  }
  if (!v.geometry)
    throw ModelError(source + ": link '" + link + "' has a visual without geometry");
  switch (v.geometry->type) {
    case urdf::Geometry::BOX: {
      const auto& box = dynamic_cast<const urdf::Box&>(*v.geometry);
      out.kind = Visual::Kind::kBox;
      out.box_size = Eigen::Vector3d(box.dim.x, box.dim.y, box.dim.z);
      break;
    }
    case urdf::Geometry::CYLINDER: {
      const auto& c = dynamic_cast<const urdf::Cylinder&>(*v.geometry);
      out.kind = Visual::Kind::kCylinder;
      out.radius = c.radius;
      out.length = c.length;
      break;
    }
    case urdf::Geometry::SPHERE:
      out.kind = Visual::Kind::kSphere;
      out.radius = dynamic_cast<const urdf::Sphere&>(*v.geometry).radius;
      break;
    case urdf::Geometry::MESH: {
      const auto& m = dynamic_cast<const urdf::Mesh&>(*v.geometry);
      out.kind = Visual::Kind::kMesh;
      out.mesh_filename = m.filename;
      out.mesh_scale = Eigen::Vector3d(m.scale.x, m.scale.y, m.scale.z);
      break;
    }
  }
  return out;
}

// urdfdom reports what is wrong through console_bridge, which prints it; collect the
// messages instead, so that they go into the one error the caller sees
class CollectMessages : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_WARN)
      messages += (messages.empty() ? "" : "; ") + text;
  }
  std::string messages;
};

urdf::ModelInterfaceSharedPtr parse_urdf(const std::string& xml, std::string* messages) {
  static std::mutex mutex;  // console_bridge's handler is process-wide
  std::lock_guard<std::mutex> lock(mutex);
  CollectMessages collect;
  console_bridge::useOutputHandler(&collect);
  urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  console_bridge::restorePreviousOutputHandler();
  *messages = collect.messages;
  if (!model)
    return model;
  // urdfdom holds each link's child links by shared_ptr, so joints that form a loop (a link
  // its own child, or two links each other's) build a cycle that outlives the model: a
  // leak found by fuzz/urdf (fuzz/regressions/urdf/joint_loop_leak.txt). The pointer
  // returned here cuts every link's children when its last owner lets go.
  urdf::ModelInterface* raw = model.get();
  return urdf::ModelInterfaceSharedPtr(raw, [model](urdf::ModelInterface* m) mutable {
    for (auto& [name, link] : m->links_) {
      link->child_links.clear();
      link->child_joints.clear();
    }
    model.reset();
  });
}

// The offset of the first byte of `text` that is not well-formed UTF-8 (a NUL counts as
// bad), or npos. urdfdom's XML parser, TinyXML, steps over a UTF-8 sequence by the length
// its lead byte announces: a lead byte among the last bytes of the text makes it read past
// the end of the buffer (heap-buffer-overflow inside TinyXML, found by ropes_sim's
// fuzz/urdf with a URDF ending in 0xda). So a URDF must be UTF-8 text, checked first.
std::size_t first_bad_utf8(const std::string& text) {
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = p[i];
    std::size_t len = 0;
    unsigned char low = 0x80, high = 0xbf;  // the second byte's range
    if (c == 0)
      return i;
    if (c < 0x80) {
      ++i;
      continue;
    }
    if (c >= 0xc2 && c <= 0xdf) {
      len = 2;
    } else if (c >= 0xe0 && c <= 0xef) {
      len = 3;
      low = c == 0xe0 ? 0xa0 : 0x80;   // no overlong forms
      high = c == 0xed ? 0x9f : 0xbf;  // no surrogates
    } else if (c >= 0xf0 && c <= 0xf4) {
      len = 4;
      low = c == 0xf0 ? 0x90 : 0x80;
      high = c == 0xf4 ? 0x8f : 0xbf;  // nothing above U+10FFFF
    } else {
      return i;
    }
    if (i + len > n || p[i + 1] < low || p[i + 1] > high)
      return i;
    for (std::size_t k = 2; k < len; ++k)
      if (p[i + k] < 0x80 || p[i + k] > 0xbf)
        return i;
    i += len;
  }
  return std::string::npos;
}

}  // namespace

RobotModel RobotModel::load(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in)
    throw ModelError(path.string() + ": cannot open the URDF file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), path.string(), path.parent_path());
}

RobotModel RobotModel::parse(const std::string& xml, const std::string& source,
                             const std::filesystem::path& base_dir) {
  const std::size_t bad = first_bad_utf8(xml);
  if (bad != std::string::npos) {
    char byte[8];
    std::snprintf(byte, sizeof byte, "0x%02x", static_cast<unsigned char>(xml[bad]));
    throw ModelError(source + ": byte " + std::to_string(bad) + " (" + byte +
                     ") is not UTF-8 text; a URDF must be UTF-8 (or ASCII) without NUL bytes");
  }
  std::string messages;
  const urdf::ModelInterfaceSharedPtr urdf = parse_urdf(xml, &messages);
  if (!urdf) {
    throw ModelError(source + ": not a valid URDF (urdfdom: " +
                     (messages.empty() ? std::string("no details") : messages) + ")");
  }
  const urdf::LinkConstSharedPtr root = urdf->getRoot();
  if (!root)
    throw ModelError(source + ": the URDF has no root link");

  RobotModel model;
  model.name_ = urdf->getName();
  model.base_dir_ = base_dir;
  model.source_ = source;
  // links breadth first from the root, so every parent comes before its children; a link
  // reached twice means joints that are not a tree (urdfdom accepts loops and links with
  // two parent joints), which would never end
  std::queue<std::pair<urdf::LinkConstSharedPtr, int>> queue;  // link, its parent joint
  std::set<std::string> reached;
  queue.push({root, -1});
  while (!queue.empty()) {
    const auto [link, parent_joint] = queue.front();
    queue.pop();
    if (!link || !reached.insert(link->name).second) {
      const std::string joint =
          parent_joint >= 0 ? model.joints_[static_cast<std::size_t>(parent_joint)].name : "";
      throw ModelError(source + ": joint '" + joint + "' leads to link '" +
                       (link ? link->name : std::string("?")) +
                       "' a second time; the joints must form a tree (no loops, one parent "
                       "joint per link)");
    }
    const int index = static_cast<int>(model.links_.size());
    Link out{link->name, {}, parent_joint};
    for (const auto& v : link->visual_array)
      out.visuals.push_back(to_visual(*v, source, link->name));
    model.links_.push_back(std::move(out));
    if (parent_joint >= 0)
      model.joints_[static_cast<std::size_t>(parent_joint)].child_link = index;

    for (const auto& j : link->child_joints) {
      Joint joint;
      joint.name = j->name;
      joint.parent_link = index;
      joint.X_PJ = to_isometry(j->parent_to_joint_origin_transform);
      switch (j->type) {
        case urdf::Joint::REVOLUTE:
          joint.type = JointType::kRevolute;
          break;
        case urdf::Joint::CONTINUOUS:
          joint.type = JointType::kContinuous;
          break;
        case urdf::Joint::PRISMATIC:
          joint.type = JointType::kPrismatic;
          break;
        case urdf::Joint::FIXED:
          joint.type = JointType::kFixed;
          break;
        default:
          throw ModelError(source + ": joint '" + j->name +
                           "' is floating or planar; expected revolute, continuous, prismatic "
                           "or fixed");
      }
      if (joint.type != JointType::kFixed) {
        const Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
        if (!(axis.norm() > 1e-12)) {
          throw ModelError(source + ": joint '" + j->name + "' has a zero axis");
        }
        joint.axis = axis.normalized();
      }
      if (j->limits) {
        joint.lower = j->limits->lower;
        joint.upper = j->limits->upper;
      }
      const int joint_index = static_cast<int>(model.joints_.size());
      model.joints_.push_back(joint);
      queue.push({urdf->getLink(j->child_link_name), joint_index});
    }
  }
  if (model.links_.size() != urdf->links_.size()) {
    std::string missing;
    for (const auto& [name, link] : urdf->links_) {
      if (reached.count(name) == 0)
        missing += (missing.empty() ? "'" : ", '") + name + "'";
    }
    throw ModelError(source + ": link(s) " + missing + " not reached from the root link '" +
                     root->name + "'; the joints must form one tree");
  }
  // joints in the order of their child links; movable ones are the coordinates
  std::vector<Joint> ordered;
  for (Link& link : model.links_) {
    if (link.parent_joint < 0)
      continue;
    ordered.push_back(model.joints_[static_cast<std::size_t>(link.parent_joint)]);
    link.parent_joint = static_cast<int>(ordered.size()) - 1;
  }
  model.joints_ = std::move(ordered);
  for (std::size_t i = 0; i < model.joints_.size(); ++i) {
    if (model.joints_[i].type != JointType::kFixed)
      model.movable_.push_back(static_cast<int>(i));
  }
  return model;
}

int RobotModel::link_index(const std::string& name) const {
  for (std::size_t i = 0; i < links_.size(); ++i) {
    if (links_[i].name == name)
      return static_cast<int>(i);
  }
  throw ModelError("robot '" + name_ + "' has no link '" + name + "'");
}

int RobotModel::joint_index(const std::string& name) const {
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    if (joints_[i].name == name)
      return static_cast<int>(i);
  }
  throw ModelError("robot '" + name_ + "' has no joint '" + name + "'");
}

}  // namespace ropes::sim
