#include "ropes_sim/camera.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/intervention_sampler.hpp"
#include "ropes_sim/kinematics.hpp"

namespace ropes::sim {
namespace {

// The witness: the eye on a sphere about the target, written with spherical coordinates
// rather than the rotations camera.cpp composes.
Eigen::Vector3d spherical_eye(const Camera& c) {
  const double yaw = c.yaw_deg * M_PI / 180, pitch = c.pitch_deg * M_PI / 180;
  return c.target + c.distance * Eigen::Vector3d(std::sin(yaw) * std::cos(pitch),
                                                 -std::cos(yaw) * std::cos(pitch),
                                                 -std::sin(pitch));
}

TEST(Camera, EyeFollowsYawAndPitch) {
  for (double yaw : {0.0, 45.0, 135.0, -70.0, 300.0}) {
    for (double pitch : {-30.0, -89.0, 10.0}) {
      Camera c;
      c.target = Eigen::Vector3d(0.3, -0.2, 0.5);
      c.distance = 1.7;
      c.yaw_deg = yaw;
      c.pitch_deg = pitch;
      EXPECT_LT((c.eye() - spherical_eye(c)).norm(), 1e-12) << yaw << " " << pitch;
    }
  }
  // Panda-Gym's default pitch -30 looks down from above
  EXPECT_GT(Camera().eye().z(), 0.0);
}

TEST(Camera, ViewPutsTheTargetAheadAndWorldUpUp) {
  Camera c;
  c.target = Eigen::Vector3d(-0.6, 0.1, 0.6);
  c.yaw_deg = 135;
  const Eigen::Isometry3d X_CW = c.X_CW();
  const Eigen::Vector3d p_C = X_CW * c.target;
  EXPECT_NEAR(p_C.x(), 0.0, 1e-12);
  EXPECT_NEAR(p_C.y(), 0.0, 1e-12);
  EXPECT_NEAR(p_C.z(), -c.distance, 1e-12);  // OpenGL looks along -z
  // a point above the target is up in the image
  EXPECT_GT((X_CW * (c.target + Eigen::Vector3d::UnitZ())).y(), 0.0);
  EXPECT_NEAR(X_CW.linear().determinant(), 1.0, 1e-12);
}

TEST(Camera, ProjectionIsGluPerspective) {
  Camera c;
  c.fov_y_deg = 90;
  const Eigen::Matrix4d P = c.projection(200, 100);
  // a point at depth 1 on the top edge of a 90 degree view lands at y = 1
  const Eigen::Vector4d top = P * Eigen::Vector4d(0, 1, -1, 1);
  EXPECT_NEAR(top.y() / top.w(), 1.0, 1e-12);
  const Eigen::Vector4d right = P * Eigen::Vector4d(2, 0, -1, 1);  // aspect 2
  EXPECT_NEAR(right.x() / right.w(), 1.0, 1e-12);
  const Eigen::Vector4d near = P * Eigen::Vector4d(0, 0, -c.near, 1);
  EXPECT_NEAR(near.z() / near.w(), -1.0, 1e-9);
}

TEST(Camera, BadFieldsAreNamed) {
  const auto message = [](Camera c) {
    try {
      c.check();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Camera c;
  c.distance = -1;
  EXPECT_NE(message(c).find("camera 'cam0': distance = -1, expected"), std::string::npos);
  c = Camera();
  c.fov_y_deg = 180;
  EXPECT_NE(message(c).find("fov_y_deg = 180"), std::string::npos);
  c = Camera();
  c.far = 0.05;
  EXPECT_NE(message(c).find("far = 0.05"), std::string::npos);
  c = Camera();
  c.pitch_deg = -90;
  EXPECT_NE(message(c).find("pitch_deg"), std::string::npos);
  CameraRig rig = CameraRig::two_cameras();
  rig.cameras[1].name = rig.cameras[0].name;
  EXPECT_THROW(rig.check(), std::invalid_argument);
  rig = CameraRig::single_camera();
  rig.width = 4;
  EXPECT_THROW(rig.check(), std::invalid_argument);
}

TEST(Camera, RigsAreThePapersCameraSetups) {
  const CameraRig one = CameraRig::single_camera(), two = CameraRig::two_cameras();
  one.check();
  two.check();
  ASSERT_EQ(one.cameras.size(), 1u);
  EXPECT_EQ(one.cameras[0].yaw_deg, 0.0);  // perpendicular to the arm's x-z plane
  ASSERT_EQ(two.cameras.size(), 2u);
  EXPECT_EQ(two.cameras[0].yaw_deg, 45.0);
  EXPECT_EQ(two.cameras[1].yaw_deg, 135.0);
  for (const CameraRig* rig : {&one, &two}) {
    EXPECT_EQ(rig->width, 128);
    for (const Camera& c : rig->cameras) {
      EXPECT_EQ(c.distance, 1.4);  // Panda-Gym's
      EXPECT_EQ(c.pitch_deg, -30.0);
    }
  }
}

// The installed rig files (what the Panda's dataset configs name) are the built-in rigs,
// to the bit: a dataset's id does not change with where its rig is written.
TEST(Camera, InstalledRigFilesAreTheBuiltInRigs) {
  const std::filesystem::path dir =
      std::filesystem::path(ROPES_SIM_DISTRIBUTIONS_DIR) / ".." / "rigs";
  for (const CameraRig& built_in : {CameraRig::single_camera(), CameraRig::two_cameras()}) {
    const CameraRig file = load_rig(dir / (built_in.name + ".json"));
    EXPECT_EQ(file.name, built_in.name);
    ASSERT_EQ(file.cameras.size(), built_in.cameras.size());
    for (std::size_t i = 0; i < file.cameras.size(); ++i) {
      const Camera &a = file.cameras[i], &b = built_in.cameras[i];
      EXPECT_EQ(a.name, b.name);
      EXPECT_EQ(a.target, b.target) << a.name;
      EXPECT_EQ(a.distance, b.distance) << a.name;
      EXPECT_EQ(a.yaw_deg, b.yaw_deg) << a.name;
      EXPECT_EQ(a.pitch_deg, b.pitch_deg) << a.name;
      EXPECT_EQ(a.fov_y_deg, b.fov_y_deg) << a.name;
      EXPECT_EQ(a.near, b.near) << a.name;
      EXPECT_EQ(a.far, b.far) << a.name;
    }
  }
}

// The framing the README claims: every link origin of 2000 anchors (every regime) of each
// distribution a rig is for stays inside that rig's images.
TEST(Camera, RigsKeepEveryLinkOfTheirDistributionsInView) {
  const std::filesystem::path dir = ROPES_SIM_DISTRIBUTIONS_DIR;
  const RobotModel model =
      RobotModel::load(std::filesystem::path(ROPES_SIM_URDF_DIR) / "panda.urdf");
  Kinematics kinematics(model);
  const Eigen::Vector3d base(-0.6, 0, 0);  // SceneOptions' default
  struct Case {
    const char* distribution;
    CameraRig rig;
  };
  for (const Case& c :
       {Case{"1c_independent", CameraRig::single_camera()},
        Case{"2c_independent", CameraRig::two_cameras()}, Case{"2c_ood", CameraRig::two_cameras()},
        Case{"2c_causal", CameraRig::two_cameras()}}) {
    const auto sampler = InterventionSampler::load(dir / (std::string(c.distribution) + ".json"));
    double worst = 0;
    for (const Camera& cam : c.rig.cameras) {
      const Eigen::Matrix4d P = cam.projection(c.rig.width, c.rig.height) * cam.X_CW().matrix();
      for (std::uint64_t anchor = 0; anchor < 2000; ++anchor) {
        for (const auto& q : sampler.sample_anchor(0, anchor)) {
          kinematics.set_positions(q);
          for (const auto& X : kinematics.link_poses()) {
            const Eigen::Vector4d clip = P * (base + X.translation()).homogeneous();
            worst = std::max({worst, std::abs(clip.x() / clip.w()), std::abs(clip.y() / clip.w())});
          }
        }
      }
    }
    EXPECT_LT(worst, 1.0) << c.distribution << ": a link origin leaves the image";
    std::cout << c.distribution << ": largest |NDC| of a link origin " << worst << "\n";
  }
}

}  // namespace
}  // namespace ropes::sim
