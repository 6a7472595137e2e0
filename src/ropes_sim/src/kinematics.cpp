#include "ropes_sim/kinematics.hpp"

#include <Simbody.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace ropes::sim {

namespace {

SimTK::Transform to_simtk(const Eigen::Isometry3d& X) {
  SimTK::Mat33 R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      R(r, c) = X.linear()(r, c);
  return SimTK::Transform(
      SimTK::Rotation(R, true),
      SimTK::Vec3(X.translation().x(), X.translation().y(), X.translation().z()));
}

Eigen::Isometry3d to_eigen(const SimTK::Transform& X) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      out.linear()(r, c) = X.R().asMat33()(r, c);
  out.translation() = Eigen::Vector3d(X.p()[0], X.p()[1], X.p()[2]);
  return out;
}

// a rotation taking `from` (a unit axis) onto the unit vector `axis`
Eigen::Matrix3d align(const Eigen::Vector3d& from, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond::FromTwoVectors(from, axis).toRotationMatrix();
}

}  // namespace

struct Kinematics::Impl {
  RobotModel model;
  SimTK::MultibodySystem system;
  SimTK::SimbodyMatterSubsystem matter{system};
  std::vector<SimTK::MobilizedBodyIndex> body_of_link;
  std::vector<SimTK::MobilizedBodyIndex> coordinate_body;  // one per movable joint
  SimTK::State state;

  explicit Impl(const RobotModel& m) : model(m) {
    // placeholder mass properties: only positions are computed
    const SimTK::Body::Rigid body(SimTK::MassProperties(1.0, SimTK::Vec3(0), SimTK::Inertia(1)));
    body_of_link.assign(model.links().size(), SimTK::MobilizedBodyIndex(0));
    body_of_link[0] = matter.Ground().getMobilizedBodyIndex();
    for (std::size_t l = 1; l < model.links().size(); ++l) {
      const Joint& j = model.joints()[static_cast<std::size_t>(model.links()[l].parent_joint)];
      SimTK::MobilizedBody& parent =
          matter.updMobilizedBody(body_of_link[static_cast<std::size_t>(j.parent_link)]);
      // F on the parent: the joint frame turned so the mobilizer's own axis (z for a Pin, x
      // for a Slider) is the joint axis; M on the child: the same turn, so the child frame
      // is the joint frame at q = 0
      const Eigen::Vector3d native =
          j.type == JointType::kPrismatic ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
      Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
      turn.linear() = align(native, j.axis);
      const SimTK::Transform X_PF = to_simtk(j.X_PJ * turn);
      const SimTK::Transform X_BM = to_simtk(turn);
      SimTK::MobilizedBodyIndex index;
      switch (j.type) {
        case JointType::kRevolute:
        case JointType::kContinuous:
          index = SimTK::MobilizedBody::Pin(parent, X_PF, body, X_BM).getMobilizedBodyIndex();
          break;
        case JointType::kPrismatic:
          index = SimTK::MobilizedBody::Slider(parent, X_PF, body, X_BM).getMobilizedBodyIndex();
          break;
        case JointType::kFixed:
          index = SimTK::MobilizedBody::Weld(parent, to_simtk(j.X_PJ), body, SimTK::Transform())
                      .getMobilizedBodyIndex();
          break;
      }
      body_of_link[l] = index;
    }
    for (int j : model.movable_joints()) {
      const Joint& joint = model.joints()[static_cast<std::size_t>(j)];
      coordinate_body.push_back(body_of_link[static_cast<std::size_t>(joint.child_link)]);
    }
    system.realizeTopology();
    state = system.getDefaultState();
    system.realize(state, SimTK::Stage::Position);
  }
};

Kinematics::Kinematics(const RobotModel& model) : impl_(std::make_unique<Impl>(model)) {}
Kinematics::~Kinematics() = default;

const RobotModel& Kinematics::model() const {
  return impl_->model;
}

void Kinematics::set_positions(const std::vector<double>& q) {
  const auto& movable = impl_->model.movable_joints();
  if (q.size() != movable.size()) {
    throw std::invalid_argument("Kinematics::set_positions: " + std::to_string(q.size()) +
                                " values for robot '" + impl_->model.name() + "' with " +
                                std::to_string(movable.size()) + " movable joints");
  }
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!std::isfinite(q[i])) {
      throw std::invalid_argument("Kinematics::set_positions: joint '" +
                                  impl_->model.joints()[static_cast<std::size_t>(movable[i])].name +
                                  "' is " + std::to_string(q[i]) + "; expected a finite value");
    }
    impl_->matter.getMobilizedBody(impl_->coordinate_body[i]).setOneQ(impl_->state, 0, q[i]);
  }
  impl_->system.realize(impl_->state, SimTK::Stage::Position);
}

Eigen::Isometry3d Kinematics::link_pose(int link) const {
  if (link < 0 || link >= static_cast<int>(impl_->model.links().size())) {
    throw std::invalid_argument("Kinematics::link_pose: link " + std::to_string(link) +
                                " is out of range for robot '" + impl_->model.name() + "'");
  }
  return to_eigen(
      impl_->matter.getMobilizedBody(impl_->body_of_link[static_cast<std::size_t>(link)])
          .getBodyTransform(impl_->state));
}

std::vector<Eigen::Isometry3d> Kinematics::link_poses() const {
  std::vector<Eigen::Isometry3d> poses;
  const int n = static_cast<int>(impl_->model.links().size());
  poses.reserve(static_cast<std::size_t>(n));
  for (int link = 0; link < n; ++link)
    poses.push_back(link_pose(link));
  return poses;
}

}  // namespace ropes::sim
