#pragma once
// The witness of ropes_sim's kinematics, shared by kinematics_test.cpp and ropes_sim_bench
// (its FK peer): the Panda's forward kinematics from Craig's modified DH table, written
// independently of the URDF and of Simbody. Frame i = frame i-1 * RotX(alpha) TransX(a)
// RotZ(theta_i) TransZ(d); row 7 is the flange (panda_link8).

#include <Eigen/Geometry>

#include <cmath>
#include <vector>

namespace ropes::sim::witness {

struct DhRow {
  double a, d, alpha;
};
constexpr DhRow kPandaDh[8] = {{0, 0.333, 0},
                               {0, 0, -M_PI / 2},
                               {0, 0.316, M_PI / 2},
                               {0.0825, 0, M_PI / 2},
                               {-0.0825, 0.384, -M_PI / 2},
                               {0, 0, M_PI / 2},
                               {0.088, 0, M_PI / 2},
                               {0, 0.107, 0}};

// the 8 frames (links 1..7 and the flange) for the 7 joint angles q
inline std::vector<Eigen::Isometry3d> dh_frames(const std::vector<double>& q) {
  std::vector<Eigen::Isometry3d> frames;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 8; ++i) {
    const double theta = i < 7 ? q[static_cast<std::size_t>(i)] : 0.0;
    X = X * Eigen::AngleAxisd(kPandaDh[i].alpha, Eigen::Vector3d::UnitX()) *
        Eigen::Translation3d(kPandaDh[i].a, 0, 0) *
        Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()) *
        Eigen::Translation3d(0, 0, kPandaDh[i].d);
    frames.push_back(X);
  }
  return frames;
}

}  // namespace ropes::sim::witness
