#pragma once
/// @file renderer.hpp
/// Renderer: draws a Scene offscreen with OSMesa (no display, no window system) into grey
/// 8-bit images. Each Renderer owns one OSMesa context, current on the thread that made it:
/// make, use and destroy a Renderer on one thread (other threads get std::logic_error), one
/// Renderer per thread; the Scene is shared. An image depends only on the scene, the link poses and
/// the camera: every render clears all state it uses, so it never depends on what was drawn before,
/// and the same inputs give the same bytes on any thread.

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_sim/camera.hpp"
#include "ropes_sim/scene.hpp"

namespace ropes::sim {

/// Thrown when no OpenGL context can be made (OSMesa missing or failing).
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Renderer {
 public:
  /// Makes an OSMesa context for `width` x `height` images (each in [8, 4096]) and uploads
  /// the scene's meshes and textures. Throws std::invalid_argument for a bad size,
  /// RenderError when OSMesa cannot make the context.
  Renderer(std::shared_ptr<const Scene> scene, int width, int height);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }

  /// Renders the robot with link poses X_BL (one per model link, in the robot's root frame
  /// B, which is what Kinematics::link_poses calls its world; the Scene places B in W) seen by
  /// `camera` into `image`: width * height bytes, rows top to bottom. Throws std::invalid_argument
  /// for a wrong pose count or a bad camera.
  void render(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera,
              std::uint8_t* image);
  std::vector<std::uint8_t> render(const std::vector<Eigen::Isometry3d>& X_BL,
                                   const Camera& camera);

  /// The number of pixels the robot covers in `camera`'s image (the robot alone, nothing
  /// hiding it): a check that a camera looks at the robot.
  int robot_pixels(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera);
  /// The robot's silhouette in `camera`'s image (the robot alone, nothing hiding it) into
  /// `mask`: width * height bytes, 255 where the robot is, 0 elsewhere; robot_pixels counts
  /// its 255s. Throws as render does.
  void robot_mask(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera,
                  std::uint8_t* mask);

  /// GL_RENDERER and GL_VERSION of the context, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) |
  /// 4.5 (Compatibility Profile) Mesa 22.3.6": golden images are exact for one of these.
  std::string gl_description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_, height_;
};

/// Tunes glibc's allocator for a process that renders large meshes: OSMesa (llvmpipe)
/// allocates and frees its vertex buffers every frame, and glibc's defaults return those
/// pages to the system and fault them back in each time, which made the Panda-Gym asset
/// (about 100,000 triangles) render 5x slower (14 against 70 images/s). Sets the mmap
/// threshold to 256 MiB and the trim threshold to 1 GiB (freed memory is kept for reuse, up
/// to the process's peak). Process-wide, so programs call it, not the library; idempotent.
void tune_malloc_for_rendering();

}  // namespace ropes::sim
