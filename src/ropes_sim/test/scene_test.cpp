#include "ropes_sim/scene.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace ropes::sim {
namespace {

namespace fs = std::filesystem;

TEST(Scene, AMeshThatDoesNotExistNamesTheUrdfTheLinkAndThePath) {
  const std::string urdf = R"(<robot name="r"><link name="base"><visual><geometry>
      <mesh filename="package://nowhere/meshes/x.obj"/></geometry></visual></link></robot>)";
  const RobotModel model =
      RobotModel::parse(urdf, "/tmp/r.urdf", fs::temp_directory_path() / "ropes_no_such_dir");
  try {
    Scene::build(model);
    FAIL() << "a missing mesh was accepted";
  } catch (const ModelError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("/tmp/r.urdf: link 'base': mesh 'package://nowhere/meshes/x.obj' does not "
                     "exist (looked for "),
              std::string::npos)
        << m;
  }
}

// a URDF in <tmp>/my_robot/urdf/ whose meshes are written the three ways URDFs write them
TEST(Scene, MeshPathsResolveAsPackageRelativeAndFileUrls) {
  const fs::path root = fs::temp_directory_path() / "ropes_sim_scene_paths";
  fs::remove_all(root);
  fs::create_directories(root / "my_robot" / "urdf");
  fs::create_directories(root / "my_robot" / "meshes");
  const std::string stl =
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
      "endloop\nendfacet\nendsolid t\n";
  std::ofstream(root / "my_robot" / "meshes" / "a.stl") << stl;
  std::ofstream(root / "my_robot" / "urdf" / "b.stl") << stl;
  const auto model_with = [&](const std::string& filename) {
    return RobotModel::parse(
        "<robot name='r'><link name='base'><visual><geometry><mesh filename='" + filename +
            "'/></geometry></visual></link></robot>",
        "r.urdf", root / "my_robot" / "urdf");
  };
  const fs::path a = root / "my_robot" / "meshes" / "a.stl";
  EXPECT_EQ(resolve_mesh_path("package://my_robot/meshes/a.stl", root / "my_robot" / "urdf", "r"),
            a);
  EXPECT_EQ(resolve_mesh_path("package://meshes/a.stl", root / "my_robot", "r"), a);
  EXPECT_EQ(resolve_mesh_path("b.stl", root / "my_robot" / "urdf", "r"),
            root / "my_robot" / "urdf" / "b.stl");
  EXPECT_EQ(resolve_mesh_path("file://" + a.string(), {}, "r"), a);
  for (const char* f : {"package://my_robot/meshes/a.stl", "../meshes/a.stl", "b.stl"})
    EXPECT_EQ(Scene::build(model_with(f))->meshes().front().vertex_count(), 3) << f;
  // a relative path is looked for in the URDF's directory only, not in its parents
  std::ofstream(root / "my_robot" / "c.stl") << stl;
  EXPECT_THROW(resolve_mesh_path("c.stl", root / "my_robot" / "urdf", "r"), ModelError);
  EXPECT_EQ(resolve_mesh_path("../c.stl", root / "my_robot" / "urdf", "r"),
            root / "my_robot" / "urdf" / ".." / "c.stl");
  // a file URL is absolute: never relative to the working directory
  try {
    resolve_mesh_path("file://meshes/a.stl", root, "r.urdf");
    ADD_FAILURE() << "a relative file URL resolved";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("is not an absolute file URL"), std::string::npos)
        << e.what();
  }
  // a package URL that names no file is an error, not a crash
  for (const char* f : {"package://", "package:///abs.stl"}) {
    try {
      resolve_mesh_path(f, root, "r.urdf");
      ADD_FAILURE() << f;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("names no file"), std::string::npos) << e.what();
    }
  }
  fs::remove_all(root);
}

}  // namespace
}  // namespace ropes::sim
