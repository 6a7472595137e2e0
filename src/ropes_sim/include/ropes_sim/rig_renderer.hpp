#pragma once
/// @file rig_renderer.hpp
/// RigRenderer: one instant of a dataset config's rig, rendered. Given the angles of the
/// config's distribution joints (which are every movable joint of the URDF), Simbody
/// places the links and every camera renders: the bytes of a dataset row's `images` for the
/// same angles, laid out [cameras, height, width]. What ropes-sim-stream publishes.
///
/// Owns an OSMesa context (see Renderer): make, use and destroy it on one thread.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/intervention_sampler.hpp"

namespace ropes::sim {

class RigRenderer {
 public:
  /// Loads the config's robot, distribution and scene. Throws ConfigError, ModelError,
  /// MeshError or RenderError as generate_dataset does.
  explicit RigRenderer(const DatasetConfig& config);
  ~RigRenderer();
  RigRenderer(const RigRenderer&) = delete;
  RigRenderer& operator=(const RigRenderer&) = delete;

  const InterventionSampler& sampler() const;
  /// The distribution's joints: what render() takes, in order.
  const std::vector<std::string>& joint_names() const;
  std::vector<std::string> camera_names() const;
  int cameras() const;
  int width() const;
  int height() const;
  std::size_t frame_bytes() const;
  /// Renders every camera for angles `q` (one per joint_names()) into `pixels`
  /// (frame_bytes() bytes). Throws std::invalid_argument for a wrong count.
  void render(const std::vector<double>& q, std::uint8_t* pixels);
  /// Each camera's robot silhouette for angles `q` (Renderer::robot_mask: 255 on the robot,
  /// 0 elsewhere, nothing hiding it) into `mask`, laid out as render's pixels.
  void robot_masks(const std::vector<double>& q, std::uint8_t* mask);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ropes::sim
