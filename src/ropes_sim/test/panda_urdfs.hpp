#pragma once
// The URDFs that ropes_sim's tests load, shared by kinematics_test.cpp and renderer_test.cpp:
// the workspace's Panda, and Panda-Gym's from ../shared (tests that use it skip when it is not
// there). The test target defines ROPES_SIM_URDF_DIR and ROPES_SHARED_ASSETS.

#include <filesystem>

namespace ropes::sim::test_urdfs {

inline const std::filesystem::path kPandaUrdf =
    std::filesystem::path(ROPES_SIM_URDF_DIR) / "panda.urdf";
inline const std::filesystem::path kPandaGym =
    std::filesystem::path(ROPES_SHARED_ASSETS) / "franka_panda" / "panda.urdf";

}  // namespace ropes::sim::test_urdfs
