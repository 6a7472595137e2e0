// urdf_fuzz: a robot from arbitrary URDF text and mesh files, loaded as ropes-generate
// loads one: RobotModel::load, Kinematics (Simbody) at the zero pose and the scene with its
// meshes. The input's sections (ropes_core/fuzz_input.hpp): "" is robot/robot.urdf; "obj",
// "mtl" and "stl" are robot/meshes/link.obj, link.mtl and link.stl. Each step works or is
// refused with a ModelError or MeshError naming the file.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "ropes_core/fuzz_input.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/mesh.hpp"
#include "ropes_sim/robot_model.hpp"
#include "ropes_sim/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  static const std::map<std::string, std::string> files = {{"", "robot/robot.urdf"},
                                                           {"obj", "robot/meshes/link.obj"},
                                                           {"mtl", "robot/meshes/link.mtl"},
                                                           {"stl", "robot/meshes/link.stl"}};
  scratch.clear();
  for (const core::fuzz::Section& section : core::fuzz::split_sections(data, size)) {
    const auto it = files.find(section.name);
    if (it != files.end())
      scratch.write(it->second, section.bytes);
  }
  try {
    const sim::RobotModel model = sim::RobotModel::load(scratch.path() / "robot/robot.urdf");
    if (model.links().empty())
      std::abort();
    for (const sim::Joint& joint : model.joints())
      if (joint.parent_link < 0 || joint.child_link < 0 ||
          joint.parent_link >= static_cast<int>(model.links().size()) ||
          joint.child_link >= static_cast<int>(model.links().size()))
        std::abort();
    const sim::Kinematics kinematics(model);
    (void)kinematics;
    sim::SceneOptions options;
    options.table = false;
    options.floor = false;
    sim::Scene::build(model, options);
  } catch (const sim::ModelError&) {
  } catch (const sim::MeshError&) {
  }
  return 0;
}
