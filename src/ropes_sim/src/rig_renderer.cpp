// RigRenderer: the dataset generator's render path for one configuration.
#include "ropes_sim/rig_renderer.hpp"

#include <stdexcept>
#include <string>

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

  // poses the robot at q (one angle per joint, checked) and calls draw(renderer, link poses,
  // camera, out) for each camera, out being that camera's width x height bytes of `frame`;
  // render and robot_masks differ only in what they draw
  template <typename Draw>
  void for_each_camera(const std::vector<double>& q, const char* caller, std::uint8_t* frame,
                       Draw draw) {
    if (q.size() != setup.coordinate_of_joint.size())
      throw std::invalid_argument(std::string("RigRenderer::") + caller + ": " +
                                  std::to_string(q.size()) + " angles for " +
                                  std::to_string(setup.coordinate_of_joint.size()) + " joints");
    kinematics.set_positions(setup.coordinates(q));
    const auto X_BL = kinematics.link_poses();
    const std::size_t image =
        static_cast<std::size_t>(config.rig.width) * static_cast<std::size_t>(config.rig.height);
    for (std::size_t c = 0; c < config.rig.cameras.size(); ++c)
      draw(renderer, X_BL, config.rig.cameras[c], frame + c * image);
  }
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
  impl_->for_each_camera(q, "render", pixels,
                         [](Renderer& r, const auto& X_BL, const Camera& camera,
                            std::uint8_t* out) { r.render(X_BL, camera, out); });
}

void RigRenderer::robot_masks(const std::vector<double>& q, std::uint8_t* mask) {
  impl_->for_each_camera(q, "robot_masks", mask,
                         [](Renderer& r, const auto& X_BL, const Camera& camera,
                            std::uint8_t* out) { r.robot_mask(X_BL, camera, out); });
}

}  // namespace ropes::sim
