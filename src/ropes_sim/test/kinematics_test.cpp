#include "ropes_sim/kinematics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "panda_dh.hpp"
#include "panda_urdfs.hpp"
#include "ropes_core/philox.hpp"

namespace ropes::sim {
namespace {

using test_urdfs::kPandaGym;
using test_urdfs::kPandaUrdf;

// the witness: test/panda_dh.hpp
using witness::dh_frames;

std::vector<double> random_configuration(const RobotModel& model, core::PhiloxStream& rng) {
  std::vector<double> q;
  for (int j : model.movable_joints()) {
    const Joint& joint = model.joints()[static_cast<std::size_t>(j)];
    q.push_back(joint.lower + (joint.upper - joint.lower) * rng.uniform_double());
  }
  return q;
}

TEST(RobotModel, LoadsTheWorkspacePandaWithSevenCoordinates) {
  const RobotModel panda = RobotModel::load(kPandaUrdf);
  EXPECT_EQ(panda.links()[0].name, "panda_link0");
  ASSERT_EQ(panda.movable_joints().size(), 7u);
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(
        panda
            .joints()[static_cast<std::size_t>(panda.movable_joints()[static_cast<std::size_t>(i)])]
            .name,
        "panda_joint" + std::to_string(i + 1));
  }
  const Joint& j4 = panda.joints()[static_cast<std::size_t>(panda.joint_index("panda_joint4"))];
  EXPECT_DOUBLE_EQ(j4.lower, -3.0718);
  EXPECT_DOUBLE_EQ(j4.upper, -0.0698);
  EXPECT_FALSE(
      panda.links()[static_cast<std::size_t>(panda.link_index("panda_link1"))].visuals.empty());
}

TEST(KinematicsGolden, SimbodyMatchesTheModifiedDhTableOn1000Configurations) {
  const RobotModel panda = RobotModel::load(kPandaUrdf);
  Kinematics fk(panda);
  core::PhiloxStream rng(2024, 0);
  double worst_position = 0, worst_rotation = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    const std::vector<double> q = random_configuration(panda, rng);
    fk.set_positions(q);
    const std::vector<Eigen::Isometry3d> dh = dh_frames(q);
    for (int i = 0; i < 8; ++i) {
      const Eigen::Isometry3d X =
          fk.link_pose(panda.link_index("panda_link" + std::to_string(i + 1)));
      worst_position = std::max(
          worst_position, (X.translation() - dh[static_cast<std::size_t>(i)].translation()).norm());
      worst_rotation =
          std::max(worst_rotation, (X.linear() - dh[static_cast<std::size_t>(i)].linear()).norm());
    }
  }
  EXPECT_LT(worst_position, 1e-9);
  EXPECT_LT(worst_rotation, 1e-9);
  std::printf("worst link position error %.3g m, rotation %.3g\n", worst_position, worst_rotation);
}

// The Panda-Gym asset (../shared, when present) has the same kinematics: its flange must
// follow the workspace model's in every configuration.
TEST(KinematicsGolden, PandaGymAssetHasTheSameKinematics) {
  if (!std::filesystem::exists(kPandaGym))
    GTEST_SKIP() << kPandaGym << " is not there";
  const RobotModel ours = RobotModel::load(kPandaUrdf);
  const RobotModel gym = RobotModel::load(kPandaGym);
  ASSERT_GE(gym.movable_joints().size(), 7u);
  Kinematics fk_ours(ours), fk_gym(gym);
  core::PhiloxStream rng(7, 0);
  for (int trial = 0; trial < 100; ++trial) {
    const std::vector<double> q = random_configuration(ours, rng);
    std::vector<double> q_gym(gym.movable_joints().size(), 0.0);  // fingers closed
    std::copy(q.begin(), q.end(), q_gym.begin());
    fk_ours.set_positions(q);
    fk_gym.set_positions(q_gym);
    const Eigen::Vector3d a = fk_ours.link_pose(ours.link_index("panda_link8")).translation();
    const Eigen::Vector3d b = fk_gym.link_pose(gym.link_index("panda_link8")).translation();
    ASSERT_LT((a - b).norm(), 1e-9) << "trial " << trial;
  }
}

TEST(RobotModel, RefusesBadInputNamingTheFile) {
  try {
    RobotModel::load("/nonexistent/robot.urdf");
    ADD_FAILURE() << "no exception";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/robot.urdf: cannot open"),
              std::string::npos);
  }
  try {
    RobotModel::parse("<robot name='x'><link name='a'/><joint name='j' type='revolute'>",
                      "bad.urdf");
    ADD_FAILURE() << "no exception";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.urdf: not a valid URDF (urdfdom: "),
              std::string::npos)
        << e.what();
    // urdfdom's own message (console_bridge) comes inside ours, not printed apart
    EXPECT_GT(std::string(e.what()).size(),
              std::string("bad.urdf: not a valid URDF (urdfdom: ").size() + 10)
        << e.what();
  }
  const RobotModel panda = RobotModel::load(kPandaUrdf);
  EXPECT_THROW(panda.link_index("panda_link99"), ModelError);
  Kinematics fk(panda);
  EXPECT_THROW(fk.set_positions({0.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(fk.set_positions({0, 0, 0, NAN, 0, 0, 0}), std::invalid_argument);
}

// urdfdom's TinyXML reads past the end of a text that ends inside a UTF-8 sequence (found by
// fuzz/urdf; the input is fuzz/regressions/urdf/ends_in_utf8_lead_byte.txt): such a URDF,
// or one with a NUL or a byte UTF-8 never uses, is refused before urdfdom sees it
TEST(RobotModel, RefusesTextThatIsNotUtf8BeforeTheXmlParserSeesIt) {
  const std::string robot = "<robot name='x'><link name='a'/></robot>";
  for (const auto& [text, offset] : std::vector<std::pair<std::string, std::size_t>>{
           {robot + "\xda", robot.size()},
           {"<robot name='\xf0\x9f'/>", 13},
           {std::string("<robot\0 name='x'/>", 19), 6},
           {"<robot name='\xff'/>", 13},
           {"<robot name='\xc0\xaf'/>", 13},         // an overlong '/'
           {"<robot name='\xed\xa0\x80'/>", 13}}) {  // a surrogate
    try {
      RobotModel::parse(text, "bad.urdf");
      ADD_FAILURE() << "no exception for byte " << offset;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.urdf: byte " + std::to_string(offset) + " (0x"),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("is not UTF-8 text"), std::string::npos) << e.what();
    }
  }
  // UTF-8 beyond ASCII is fine: a link called "Gelenk-ä-✓-😀"
  const RobotModel model = RobotModel::parse(
      "<robot name='x'><link name='Gelenk-\xc3\xa4-\xe2\x9c\x93-\xf0\x9f\x98\x80'/></robot>",
      "good.urdf");
  ASSERT_EQ(model.links().size(), 1u);
  EXPECT_EQ(model.links()[0].name, "Gelenk-\xc3\xa4-\xe2\x9c\x93-\xf0\x9f\x98\x80");
}

// urdfdom accepts joints that do not form a tree (a link its own child, two links each
// other's, a link with two parent joints, a loop apart from the root); the model built from
// them was walked forever, and
// urdfdom's shared_ptr cycle leaked (found by fuzz/urdf; the input is
// fuzz/regressions/urdf/joint_loop_leak.txt). Each is refused, naming a joint or the links, and
// (under LeakSanitizer) nothing leaks.
TEST(RobotModel, RefusesJointsThatDoNotFormATree) {
  const std::string links = "<link name='base'/><link name='a'/><link name='b'/>";
  auto joint = [](const std::string& name, const std::string& parent, const std::string& child) {
    return "<joint name='" + name + "' type='revolute'><parent link='" + parent +
           "'/><child link='" + child +
           "'/><axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='1' velocity='1'/></joint>";
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      // a link its own child
      {joint("j1", "base", "a") + joint("j2", "a", "a") + joint("j3", "base", "b"),
       "joint 'j2' leads to link 'a' a second time"},
      // two links each other's child, hanging from the root
      {joint("j1", "base", "a") + joint("j2", "a", "b") + joint("j3", "b", "a"),
       "joint 'j3' leads to link 'a' a second time"},
      // two parent joints for one link
      {joint("j1", "base", "a") + joint("j2", "base", "b") + joint("j3", "a", "b"),
       "joint 'j3' leads to link 'b' a second time"},
      // a loop apart from the root's tree
      {joint("j1", "a", "b") + joint("j2", "b", "a"), "link(s) 'a', 'b' not reached"}};
  for (const auto& [joints, expected] : cases) {
    const std::string xml = "<robot name='loop'>" + links + joints + "</robot>";
    try {
      RobotModel::parse(xml, "loop.urdf");
      ADD_FAILURE() << "no exception for " << joints;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("loop.urdf: "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << e.what() << " (expected '" << expected << "')";
    }
  }
}

}  // namespace
}  // namespace ropes::sim
