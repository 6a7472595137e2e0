#include "ropes_sim/scene.hpp"

#include <map>
#include <system_error>

#include "ropes_core/file_io.hpp"

namespace ropes::sim {

std::filesystem::path resolve_mesh_path(const std::string& filename,
                                        const std::filesystem::path& urdf_dir,
                                        const std::string& source) {
  namespace fs = std::filesystem;
  std::vector<fs::path> tried;
  const auto found = [&](const fs::path& p) {
    tried.push_back(p);
    return core::is_regular_file(p);  // a name too long or a loop of links: not found
  };
  const std::string kPackage = "package://", kFile = "file://";
  if (filename.rfind(kFile, 0) == 0) {
    const fs::path p = filename.substr(kFile.size());
    if (!p.is_absolute())  // a URL's path; never one relative to the working directory
      throw ModelError(source + ": mesh '" + filename +
                       "' is not an absolute file URL; expected file:///path/to/mesh");
    if (found(p))
      return p;
  } else if (filename.rfind(kPackage, 0) == 0) {
    // package://PKG/rest: PKG may be the URDF's own directory (or a parent) by name, or, as
    // many exported robots write it, the first folder below the URDF's directory
    const fs::path rest = filename.substr(kPackage.size());
    if (rest.empty() || rest.is_absolute())
      throw ModelError(source + ": mesh '" + filename +
                       "' names no file; expected package://PACKAGE/path/to/mesh");
    const fs::path base = urdf_dir.empty() ? fs::path(".") : urdf_dir;
    const fs::path pkg = *rest.begin();
    const fs::path below = rest.lexically_relative(pkg);
    for (fs::path dir = fs::absolute(base); !dir.empty(); dir = dir.parent_path()) {
      if (found(dir / rest))
        return dir / rest;
      if (dir.filename() == pkg && found(dir / below))
        return dir / below;
      if (dir == dir.parent_path())
        break;
    }
  } else {
    const fs::path p(filename);
    const fs::path full = p.is_absolute() ? p : (urdf_dir.empty() ? fs::path(".") : urdf_dir) / p;
    if (found(full))
      return full;
  }
  std::string places;
  for (std::size_t i = 0; i < tried.size() && i < 6; ++i)
    places += (i ? ", " : "") + tried[i].string();
  if (tried.size() > 6)
    places += ", ...";
  throw ModelError(source + ": mesh '" + filename + "' does not exist (looked for " + places + ")");
}

std::vector<std::string> Scene::warnings() const {
  std::vector<std::string> all;
  for (const Mesh& m : meshes_)
    all.insert(all.end(), m.warnings.begin(), m.warnings.end());
  return all;
}

Eigen::Isometry3d Scene::X_WB() const {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = options_.robot_base;
  return X;
}

std::shared_ptr<const Scene> Scene::build(const RobotModel& model, const SceneOptions& options) {
  auto scene = std::make_shared<Scene>();
  scene->model_ = model;
  scene->options_ = options;
  const std::string& source = model.source();
  std::map<std::string, int> loaded;  // resolved mesh path -> mesh index
  const auto add_mesh = [&](Mesh mesh) {
    scene->meshes_.push_back(std::move(mesh));
    return static_cast<int>(scene->meshes_.size()) - 1;
  };
  const int segments = options.primitive_segments;

  const auto& links = model.links();
  for (std::size_t l = 0; l < links.size(); ++l) {
    for (const Visual& v : links[l].visuals) {
      SceneItem item;
      item.link = static_cast<int>(l);
      item.X_LV = v.X_LV;
      item.rgb = v.rgba.head<3>().cast<float>();
      switch (v.kind) {
        case Visual::Kind::kBox:
          item.mesh = add_mesh(make_box(v.box_size));
          break;
        case Visual::Kind::kCylinder:
          item.mesh = add_mesh(make_cylinder(v.radius, v.length, segments));
          break;
        case Visual::Kind::kSphere:
          item.mesh = add_mesh(make_sphere(v.radius, segments));
          break;
        case Visual::Kind::kMesh: {
          const std::filesystem::path path = resolve_mesh_path(
              v.mesh_filename, model.base_dir(), source + ": link '" + links[l].name + "'");
          const auto it = loaded.find(path.string());
          if (it != loaded.end()) {
            item.mesh = it->second;
          } else {
            item.mesh = add_mesh(load_mesh(path));
            loaded.emplace(path.string(), item.mesh);
          }
          item.scale = v.mesh_scale;
          break;
        }
      }
      scene->items_.push_back(item);
    }
  }
  // Panda-Gym's table and floor
  if (options.table) {
    SceneItem table;
    table.mesh = add_mesh(make_box(options.table_size));
    table.X_LV.translation() = options.table_center;
    table.rgb = options.table_rgb;
    scene->items_.push_back(table);
  }
  if (options.floor) {
    SceneItem floor;
    const double e = 2 * options.floor_half_extent;
    floor.mesh = add_mesh(make_box(Eigen::Vector3d(e, e, 0.02)));
    floor.X_LV.translation() = Eigen::Vector3d(0, 0, options.floor_z - 0.01);
    floor.rgb = options.floor_rgb;
    scene->items_.push_back(floor);
  }
  return scene;
}

}  // namespace ropes::sim
