#pragma once
/// @file camera.hpp
/// Camera and CameraRig: where the cameras are, parametrised as PyBullet's
/// computeViewMatrixFromYawPitchRoll (z up) and computeProjectionMatrixFOV are, which is how
/// Panda-Gym places its camera. A rig is the set of cameras that see every sample.
///
/// Frames (Drake's monograms): W the world, z up; C a camera, OpenGL's convention (x right,
/// y up, looking along -z).

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace ropes::sim {

struct Camera {
  std::string name = "cam0";
  /// The point the camera looks at, in W.
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  /// Distance from the target to the eye (m), > 0.
  double distance = 1.4;
  /// The eye starts at target + (0, -distance, 0) (on the -y side, looking along +y), is
  /// pitched about x by `pitch_deg` (negative: from above) and turned about z by `yaw_deg`.
  double yaw_deg = 0.0;
  double pitch_deg = -30.0;
  /// Vertical field of view (degrees, in (0, 180)) and clip distances (0 < near < far).
  double fov_y_deg = 60.0;
  double near = 0.1, far = 100.0;

  /// The eye position in W.
  Eigen::Vector3d eye() const;
  /// X_CW: world to camera (OpenGL's view matrix), z up in W kept up in the image.
  Eigen::Isometry3d X_CW() const;
  /// The OpenGL projection matrix for an image `width` x `height`.
  Eigen::Matrix4d projection(int width, int height) const;
  /// What is wrong with the camera: a message naming the camera, the field, the value and
  /// what is expected when a field is out of range or not finite; "" when nothing is.
  std::string problem() const;
  /// Throws std::invalid_argument with problem() when there is one.
  void check() const;
};

/// The cameras that see every sample, and the image size they render at.
struct CameraRig {
  std::string name;
  std::vector<Camera> cameras;
  int width = 128, height = 128;

  /// What is wrong with the rig ("" when nothing is): no camera, duplicate names, a size
  /// outside [8, 4096] or a bad camera (Camera::problem).
  std::string problem() const;
  /// Throws std::invalid_argument with problem() when there is one.
  void check() const;

  /// The single-camera rig of the 1C experiments: perpendicular to the arm's plane
  /// (yaw 0), framed so that the Panda fills most of a 128x128 image over the paper's poses.
  static CameraRig single_camera();
  /// The two-camera rig of the 2C experiments: yaw 45 and 135, framed for joints 1-6 moving.
  static CameraRig two_cameras();
};

}  // namespace ropes::sim
