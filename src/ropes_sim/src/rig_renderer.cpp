// RigRenderer: the dataset generator's render path for one configuration.
#include "ropes_sim/rig_renderer.hpp"

#include <stdexcept>

#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/renderer.hpp"
#include "ropes_sim/robot_model.hpp"
#include "ropes_sim/scene.hpp"

namespace ropes::sim {

struct RigRenderer::Impl {
  DatasetConfig config;
  RobotModel model;
  InterventionSampler sampler;
  std::vector<std::size_t> coordinate_of_joint;
  std::shared_ptr<const Scene> scene;
  Kinematics kinematics;
  Renderer renderer;

  explicit Impl(const DatasetConfig& c)
      : config(c),
        model(RobotModel::load(c.robot)),
        sampler(InterventionSampler::load(c.distribution)),
        scene(Scene::build(model)),
        kinematics(model),
        renderer(scene, c.rig.width, c.rig.height) {
    const auto& movable = model.movable_joints();
    for (const std::string& name : sampler.joint_names()) {
      std::size_t found = movable.size();
      for (std::size_t k = 0; k < movable.size(); ++k)
        if (model.joints()[static_cast<std::size_t>(movable[k])].name == name)
          found = k;
      if (found == movable.size())
        throw ConfigError(c.distribution.string() + ": joint '" + name +
                          "' is not a movable joint of robot '" + model.name() + "' (" +
                          c.robot.string() + ")");
      coordinate_of_joint.push_back(found);
    }
  }
};

RigRenderer::RigRenderer(const DatasetConfig& config) : impl_(std::make_unique<Impl>(config)) {}
RigRenderer::~RigRenderer() = default;

const InterventionSampler& RigRenderer::sampler() const {
  return impl_->sampler;
}
const std::vector<std::string>& RigRenderer::joint_names() const {
  return impl_->sampler.joint_names();
}
std::vector<std::string> RigRenderer::camera_names() const {
  std::vector<std::string> out;
  for (const Camera& c : impl_->config.rig.cameras)
    out.push_back(c.name);
  return out;
}
int RigRenderer::cameras() const {
  return static_cast<int>(impl_->config.rig.cameras.size());
}
int RigRenderer::width() const {
  return impl_->config.rig.width;
}
int RigRenderer::height() const {
  return impl_->config.rig.height;
}
std::size_t RigRenderer::frame_bytes() const {
  return static_cast<std::size_t>(cameras()) * static_cast<std::size_t>(width()) *
         static_cast<std::size_t>(height());
}

void RigRenderer::render(const std::vector<double>& q, std::uint8_t* pixels) {
  Impl& s = *impl_;
  if (q.size() != s.coordinate_of_joint.size())
    throw std::invalid_argument("RigRenderer::render: " + std::to_string(q.size()) +
                                " angles for " + std::to_string(s.coordinate_of_joint.size()) +
                                " joints");
  std::vector<double> coordinates(s.model.movable_joints().size(), 0.0);
  for (std::size_t j = 0; j < q.size(); ++j)
    coordinates[s.coordinate_of_joint[j]] = q[j];
  s.kinematics.set_positions(coordinates);
  const auto X_BL = s.kinematics.link_poses();
  const std::size_t image = static_cast<std::size_t>(width()) * static_cast<std::size_t>(height());
  for (std::size_t c = 0; c < s.config.rig.cameras.size(); ++c)
    s.renderer.render(X_BL, s.config.rig.cameras[c], pixels + c * image);
}

}  // namespace ropes::sim
