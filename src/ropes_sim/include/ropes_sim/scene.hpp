#pragma once
/// @file scene.hpp
/// Scene: what the renderer draws, on the CPU side and immutable, so that renderers on
/// several threads share one copy: the robot's visual shapes as meshes attached to its
/// links, Panda-Gym's table and floor, the background and the shading constants
/// (DESIGN.md, "Scene").

#include <Eigen/Geometry>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "ropes_sim/mesh.hpp"
#include "ropes_sim/robot_model.hpp"

namespace ropes::sim {

/// Where things are and how they are lit. Defaults: Panda-Gym's scene (robot base at
/// (-0.6, 0, 0); table 1.1 x 0.7 x 0.4 with its top at z = 0, centred at x = -0.3; floor
/// 6 x 6 m with its top at z = -0.4; white background) and PyBullet TinyRenderer's shading:
/// colour = c * (ambient + diffuse * max(0, n.l)) + specular * max(0, r.v)^shininess, with
/// l = normalize(-50, 30, 100) in W. Images are grey: 0.299 R + 0.587 G + 0.114 B.
struct SceneOptions {
  Eigen::Vector3d robot_base = Eigen::Vector3d(-0.6, 0.0, 0.0);
  bool table = true;
  Eigen::Vector3d table_size = Eigen::Vector3d(1.1, 0.7, 0.4);
  Eigen::Vector3d table_center = Eigen::Vector3d(-0.3, 0.0, -0.2);
  Eigen::Vector3f table_rgb = Eigen::Vector3f(0.95f, 0.95f, 0.95f);
  bool floor = true;
  double floor_z = -0.4;
  double floor_half_extent = 3.0;  // Panda-Gym's plane: a 6 x 6 x 0.02 box, top at floor_z
  Eigen::Vector3f floor_rgb = Eigen::Vector3f(0.15f, 0.15f, 0.15f);
  Eigen::Vector3f background_rgb = Eigen::Vector3f(1.0f, 1.0f, 1.0f);
  Eigen::Vector3d light_direction = Eigen::Vector3d(-50.0, 30.0, 100.0);
  float ambient = 0.6f, diffuse = 0.35f, specular = 0.05f, shininess = 20.0f;
  /// facets around a URDF cylinder or sphere
  int primitive_segments = 32;
};

/// One drawable: mesh `mesh` of Scene::meshes(), placed at X_LV (with `scale`) in link
/// `link` (a robot visual) or at X_LV in W when `link` is -1 (table, floor), tinted by
/// `rgb` (the URDF material's colour).
struct SceneItem {
  int link = -1;
  int mesh = 0;
  Eigen::Isometry3d X_LV = Eigen::Isometry3d::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  Eigen::Vector3f rgb = Eigen::Vector3f::Ones();
};

class Scene {
 public:
  /// Builds the scene of `model`: a mesh per primitive, each mesh file loaded once.
  /// Mesh paths (resolve_mesh_path), the only places a mesh is looked for: a relative path
  /// (`../` included) in the URDF's directory; "package://PKG/rest" as DIR/PKG/rest, or as
  /// DIR/rest when DIR is named PKG, for DIR the URDF's directory and then each of its
  /// parents (the first that exists wins, as ROS does for a package found on the path);
  /// "file:///abs" and an absolute path as written. Meshes are only read. Throws
  /// ModelError naming the URDF, the link, the path as written and the places looked in
  /// when a mesh file does not exist, or for "package://" without a path and a "file://"
  /// URL that is not absolute; MeshError (naming the mesh file and line) when one cannot
  /// be read.
  static std::shared_ptr<const Scene> build(const RobotModel& model,
                                            const SceneOptions& options = {});

  const RobotModel& model() const { return model_; }
  const SceneOptions& options() const { return options_; }
  const std::vector<Mesh>& meshes() const { return meshes_; }
  const std::vector<SceneItem>& items() const { return items_; }
  /// The meshes' warnings (Mesh::warnings), for a program to print.
  std::vector<std::string> warnings() const;
  /// X_WB: the robot's root link in W.
  Eigen::Isometry3d X_WB() const;

 private:
  RobotModel model_;
  SceneOptions options_;
  std::vector<Mesh> meshes_;
  std::vector<SceneItem> items_;
};

/// Finds the file a URDF mesh path names (see Scene::build); throws ModelError naming
/// `source`, the path and the places looked in.
std::filesystem::path resolve_mesh_path(const std::string& filename,
                                        const std::filesystem::path& urdf_dir,
                                        const std::string& source);

}  // namespace ropes::sim
