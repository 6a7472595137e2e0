#pragma once
/// @file kinematics.hpp
/// Kinematics: forward kinematics of a RobotModel on Simbody. Revolute and continuous
/// joints become Pin mobilizers about the joint axis, prismatic ones Sliders, fixed ones
/// welds. Simbody stays inside kinematics.cpp.

#include <Eigen/Geometry>

#include <memory>
#include <vector>

#include "ropes_sim/robot_model.hpp"

namespace ropes::sim {

class Kinematics {
 public:
  /// Builds the multibody system of `model` (which must outlive nothing: it is copied).
  explicit Kinematics(const RobotModel& model);
  ~Kinematics();
  Kinematics(const Kinematics&) = delete;
  Kinematics& operator=(const Kinematics&) = delete;

  /// Sets the coordinates, one per movable joint in model.movable_joints() order (radians
  /// or metres; limits are not enforced, as PyBullet's resetJointState does not), and
  /// realizes positions. Throws std::invalid_argument for a wrong count or a non-finite
  /// value, naming the joint. Cost: a few microseconds for the Panda.
  void set_positions(const std::vector<double>& q);

  /// X_WL: the pose of link `link` in the world (root link) frame, for the last positions.
  Eigen::Isometry3d link_pose(int link) const;
  /// X_WL of every link, in model.links() order (what Renderer::render takes).
  std::vector<Eigen::Isometry3d> link_poses() const;

  const RobotModel& model() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ropes::sim
