#include "ropes_sim/camera.hpp"

#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

namespace ropes::sim {

namespace {

double radians(double deg) {
  return deg * M_PI / 180.0;
}

std::string field(const Camera& c, const char* name, double value, const char* expected) {
  std::ostringstream s;
  s.precision(17);
  s << "camera '" << c.name << "': " << name << " = " << value << ", expected " << expected;
  return s.str();
}

}  // namespace

Eigen::Vector3d Camera::eye() const {
  const Eigen::Vector3d start(0.0, -distance, 0.0);
  return target + Eigen::AngleAxisd(radians(yaw_deg), Eigen::Vector3d::UnitZ()) *
                      (Eigen::AngleAxisd(radians(pitch_deg), Eigen::Vector3d::UnitX()) * start);
}

Eigen::Isometry3d Camera::X_CW() const {
  // look-at: the camera's -z towards the target, its y as close to W's z as possible
  const Eigen::Vector3d p_WC = eye();
  const Eigen::Vector3d back = (p_WC - target).normalized();
  const Eigen::Vector3d right = Eigen::Vector3d::UnitZ().cross(back).normalized();
  const Eigen::Vector3d up = back.cross(right);
  Eigen::Matrix3d R_WC;
  R_WC << right, up, back;
  Eigen::Isometry3d X_WC = Eigen::Isometry3d::Identity();
  X_WC.linear() = R_WC;
  X_WC.translation() = p_WC;
  return X_WC.inverse();
}

Eigen::Matrix4d Camera::projection(int width, int height) const {
  // gluPerspective, as PyBullet's computeProjectionMatrixFOV
  const double f = 1.0 / std::tan(radians(fov_y_deg) / 2.0);
  const double aspect = static_cast<double>(width) / height;
  Eigen::Matrix4d P = Eigen::Matrix4d::Zero();
  P(0, 0) = f / aspect;
  P(1, 1) = f;
  P(2, 2) = (far + near) / (near - far);
  P(2, 3) = 2.0 * far * near / (near - far);
  P(3, 2) = -1.0;
  return P;
}

std::string Camera::problem() const {
  if (!target.allFinite())
    return "camera '" + name + "': target is not finite";
  if (!(distance > 0.0) || !std::isfinite(distance))
    return field(*this, "distance", distance, "a finite value > 0 (m)");
  if (!std::isfinite(yaw_deg))
    return field(*this, "yaw_deg", yaw_deg, "a finite angle");
  if (!(pitch_deg > -90.0 && pitch_deg < 90.0))
    return field(*this, "pitch_deg", pitch_deg,
                 "a value in (-90, 90) (the view must not be vertical)");
  if (!(fov_y_deg > 0.0 && fov_y_deg < 180.0))
    return field(*this, "fov_y_deg", fov_y_deg, "a value in (0, 180)");
  if (!(near > 0.0) || !std::isfinite(near))
    return field(*this, "near", near, "a finite value > 0");
  if (!(far > near) || !std::isfinite(far))
    return field(*this, "far", far, "a finite value > near");
  return "";
}

void Camera::check() const {
  const std::string why = problem();
  if (!why.empty())
    throw std::invalid_argument(why);
}

std::string CameraRig::problem() const {
  if (cameras.empty())
    return "camera rig '" + name + "' has no camera";
  if (width < 8 || width > 4096 || height < 8 || height > 4096)
    return "camera rig '" + name + "': image size " + std::to_string(width) + "x" +
           std::to_string(height) + ", expected width and height in [8, 4096]";
  std::set<std::string> names;
  for (const Camera& c : cameras) {
    const std::string why = c.problem();
    if (!why.empty())
      return why;
    if (!names.insert(c.name).second)
      return "camera rig '" + name + "': two cameras are called '" + c.name + "'";
  }
  return "";
}

void CameraRig::check() const {
  const std::string why = problem();
  if (!why.empty())
    throw std::invalid_argument(why);
}

namespace {

// Panda-Gym's camera (distance 1.4, pitch -30, near 0.1, far 100) aimed at the middle of the
// space the arm sweeps under the rig's distributions, with a field of view that keeps every
// link origin of 2000 sampled anchors inside the image (package README, "Camera rigs").
Camera framed(const std::string& name, double yaw_deg, const Eigen::Vector3d& target,
              double fov_y_deg) {
  Camera c;
  c.name = name;
  c.target = target;
  c.distance = 1.4;
  c.yaw_deg = yaw_deg;
  c.pitch_deg = -30.0;
  c.fov_y_deg = fov_y_deg;
  return c;
}

}  // namespace

CameraRig CameraRig::single_camera() {
  CameraRig rig;
  rig.name = "single_camera";
  rig.cameras = {framed("cam0", 0.0, Eigen::Vector3d(-0.6, 0.0, 0.62), 68.0)};
  return rig;
}

CameraRig CameraRig::two_cameras() {
  CameraRig rig;
  rig.name = "two_cameras";
  const Eigen::Vector3d target(-0.55, 0.0, 0.45);
  rig.cameras = {framed("yaw45", 45.0, target, 80.0), framed("yaw135", 135.0, target, 80.0)};
  return rig;
}

}  // namespace ropes::sim
