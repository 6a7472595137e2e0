#pragma once
// What the dataset generator and RigRenderer share: a config's robot and distribution, and
// the map from the distribution's joints to the model's coordinates (private to ropes_sim).
#include <algorithm>
#include <string>
#include <vector>

#include "ropes_core/dataset.hpp"
#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/intervention_sampler.hpp"
#include "ropes_sim/robot_model.hpp"

namespace ropes::sim::detail {

// what every run needs, loaded once
struct Setup {
  RobotModel model;
  InterventionSampler sampler;
  std::vector<int> coordinate_of_joint;  // sampler joint -> model coordinate
  int regimes = 0, cameras = 0, width = 0, height = 0, joints = 0;

  explicit Setup(const DatasetConfig& config)
      : model(RobotModel::load(config.robot)),
        sampler(InterventionSampler::load(config.distribution)) {
    const auto& movable = model.movable_joints();
    std::string movable_names;
    for (int m : movable)
      movable_names +=
          (movable_names.empty() ? "" : ", ") + model.joints()[static_cast<std::size_t>(m)].name;
    for (const std::string& name : sampler.joint_names()) {
      int found = -1;
      for (std::size_t c = 0; c < movable.size(); ++c)
        if (model.joints()[static_cast<std::size_t>(movable[c])].name == name)
          found = static_cast<int>(c);
      if (found < 0)
        throw ConfigError(config.distribution.string() + ": joint '" + name +
                          "' is not a movable joint of robot '" + model.name() + "' (" +
                          config.robot.string() + "), whose movable joints are " +
                          (movable_names.empty() ? "none" : movable_names));
      coordinate_of_joint.push_back(found);
    }
    // every movable joint's angle is decided by the distribution: one it does not name would
    // sit at 0 in every image, unnoticed
    for (int m : movable) {
      const std::string& name = model.joints()[static_cast<std::size_t>(m)].name;
      const auto& named = sampler.joint_names();
      if (std::find(named.begin(), named.end(), name) == named.end())
        throw ConfigError(config.robot.string() + ": movable joint '" + name + "' of robot '" +
                          model.name() + "' is not in the distribution " +
                          config.distribution.string() +
                          "; name it in \"joints\" and give it a value in \"held\" (or a "
                          "distribution), so that every joint's angle is decided");
    }
    regimes = static_cast<int>(sampler.regime_names().size());
    cameras = static_cast<int>(config.rig.cameras.size());
    width = config.rig.width;
    height = config.rig.height;
    joints = static_cast<int>(sampler.joint_names().size());
  }

  // the model's coordinates for one sampled configuration (other joints at 0)
  std::vector<double> coordinates(const std::vector<double>& q) const {
    std::vector<double> out(model.movable_joints().size(), 0.0);
    for (std::size_t j = 0; j < q.size(); ++j)
      out[static_cast<std::size_t>(coordinate_of_joint[j])] = q[j];
    return out;
  }

  std::vector<core::ColumnSpec> columns() const {
    return {{"images", core::DType::kU8, {cameras, height, width}},
            {"angles", core::DType::kF32, {joints}},
            {"regime", core::DType::kI32, {}},
            {"anchor", core::DType::kI64, {}}};
  }
};

}  // namespace ropes::sim::detail
