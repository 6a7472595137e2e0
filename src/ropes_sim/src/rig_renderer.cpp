// RigRenderer: the dataset generator's render path for one configuration.
#include "ropes_sim/rig_renderer.hpp"

#include <stdexcept>

#include "dataset_setup.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/renderer.hpp"
#include "ropes_sim/robot_model.hpp"
#include "ropes_sim/scene.hpp"

namespace ropes::sim {

struct RigRenderer::Impl {
  DatasetConfig config;
  detail::Setup setup;
  std::shared_ptr<const Scene> scene;
  Kinematics kinematics;
  Renderer renderer;

  explicit Impl(const DatasetConfig& c)
      : config(c),
        setup(c),
        scene(Scene::build(setup.model)),
        kinematics(setup.model),
        renderer(scene, c.rig.width, c.rig.height) {}
};

RigRenderer::RigRenderer(const DatasetConfig& config) : impl_(std::make_unique<Impl>(config)) {}
RigRenderer::~RigRenderer() = default;

const InterventionSampler& RigRenderer::sampler() const {
  return impl_->setup.sampler;
}
const std::vector<std::string>& RigRenderer::joint_names() const {
  return impl_->setup.sampler.joint_names();
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
  if (q.size() != s.setup.coordinate_of_joint.size())
    throw std::invalid_argument("RigRenderer::render: " + std::to_string(q.size()) +
                                " angles for " +
                                std::to_string(s.setup.coordinate_of_joint.size()) + " joints");
  s.kinematics.set_positions(s.setup.coordinates(q));
  const auto X_BL = s.kinematics.link_poses();
  const std::size_t image = static_cast<std::size_t>(width()) * static_cast<std::size_t>(height());
  for (std::size_t c = 0; c < s.config.rig.cameras.size(); ++c)
    s.renderer.render(X_BL, s.config.rig.cameras[c], pixels + c * image);
}

void RigRenderer::robot_masks(const std::vector<double>& q, std::uint8_t* mask) {
  Impl& s = *impl_;
  if (q.size() != s.setup.coordinate_of_joint.size())
    throw std::invalid_argument("RigRenderer::robot_masks: " + std::to_string(q.size()) +
                                " angles for " +
                                std::to_string(s.setup.coordinate_of_joint.size()) + " joints");
  s.kinematics.set_positions(s.setup.coordinates(q));
  const auto X_BL = s.kinematics.link_poses();
  const std::size_t image = static_cast<std::size_t>(width()) * static_cast<std::size_t>(height());
  for (std::size_t c = 0; c < s.config.rig.cameras.size(); ++c)
    s.renderer.robot_mask(X_BL, s.config.rig.cameras[c], mask + c * image);
}

}  // namespace ropes::sim
