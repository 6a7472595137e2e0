#include "ropes_sim/scene.hpp"

#include <gtest/gtest.h>

#include <filesystem>
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

}  // namespace
}  // namespace ropes::sim
