#pragma once
/// @file robot_model.hpp
/// RobotModel: a robot as a URDF describes it (links, joints, visual shapes), parsed with
/// urdfdom into the workspace's own types, so urdfdom's types stay out of public headers.

#include <Eigen/Geometry>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::sim {

/// Thrown for a URDF that cannot be read or used; the message names the file.
class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class JointType { kRevolute, kContinuous, kPrismatic, kFixed };

/// One visual shape of a link. X_LV: the shape's frame in the link frame.
struct Visual {
  enum class Kind { kBox, kCylinder, kSphere, kMesh };
  Kind kind = Kind::kBox;
  Eigen::Isometry3d X_LV = Eigen::Isometry3d::Identity();
  Eigen::Vector3d box_size = Eigen::Vector3d::Zero();  // kBox: full extents
  double radius = 0.0;                                 // kCylinder, kSphere
  double length = 0.0;                                 // kCylinder (along its z axis)
  std::string mesh_filename;                           // kMesh, as written in the URDF
  Eigen::Vector3d mesh_scale = Eigen::Vector3d::Ones();
  Eigen::Vector4d rgba = Eigen::Vector4d(0.8, 0.8, 0.8, 1.0);
};

struct Link {
  std::string name;
  std::vector<Visual> visuals;
  int parent_joint = -1;  // index into joints(); -1 for the root
};

struct Joint {
  std::string name;
  JointType type = JointType::kFixed;
  int parent_link = -1, child_link = -1;                   // indices into links()
  Eigen::Isometry3d X_PJ = Eigen::Isometry3d::Identity();  // joint frame in the parent link
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();         // unit, in the joint frame
  double lower = 0.0, upper = 0.0;                         // limits (revolute, prismatic)
};

/// A tree of links connected by joints. Links are ordered parents first (the root is
/// link 0); joints in the order of their child links. The movable joints (revolute,
/// continuous, prismatic), in that order, are the robot's coordinates.
class RobotModel {
 public:
  /// Parses the URDF file at `path`. Throws ModelError naming the file when it cannot be
  /// read, is not a URDF urdfdom accepts, or has a joint type the workspace does not
  /// support (floating, planar).
  static RobotModel load(const std::filesystem::path& path);
  /// Parses URDF text; `source` names it in messages and `base_dir` resolves relative
  /// mesh paths.
  static RobotModel parse(const std::string& xml, const std::string& source,
                          const std::filesystem::path& base_dir = {});

  const std::string& name() const { return name_; }
  const std::vector<Link>& links() const { return links_; }
  const std::vector<Joint>& joints() const { return joints_; }
  /// Indices into joints() of the movable joints, in coordinate order.
  const std::vector<int>& movable_joints() const { return movable_; }
  /// Index of the link or joint called `name`; throws ModelError naming it and the model.
  int link_index(const std::string& name) const;
  int joint_index(const std::string& name) const;
  /// Directory of the URDF file (mesh paths are relative to it).
  const std::filesystem::path& base_dir() const { return base_dir_; }
  /// The URDF file (or the `source` given to parse) the model came from, for messages.
  const std::string& source() const { return source_; }

 private:
  std::string name_;
  std::vector<Link> links_;
  std::vector<Joint> joints_;
  std::vector<int> movable_;
  std::filesystem::path base_dir_;
  std::string source_;
};

}  // namespace ropes::sim
