// SPDX-License-Identifier: Apache-2.0
#include <hydrus_fitting/sim/simulated_hydrus.hpp>

#include <stdexcept>

#include <fmt/format.h>

#include <sim/scenes/hydrus.hpp>

namespace tinyline::hydrus_fitting {

SimulatedHydrus::SimulatedHydrus(sim::SimulatedSystem& system, const RobotModel& model)
    : system_(&system), model_(&model) {
  const std::string scene = system.scene_name();
  for (const auto& s : model.sensors()) {
    try {
      sensors_.push_back(system.sensor_index(s.name));
    } catch (const std::exception& e) {
      throw std::runtime_error(
          fmt::format("scene '{}' has no sensor '{}' of robot '{}': {}", scene, s.name, model.name(), e.what()));
    }
  }
  for (const auto& l : model.links()) {
    const auto id = system.with_scene([&](const sim::Scene& sc) { return sc.world.find(l.name); });
    if (!id)
      throw std::runtime_error(
          fmt::format("scene '{}' has no object '{}' (a link of robot '{}')", scene, l.name, model.name()));
    links_.push_back(*id);
  }
  auto truth = [&](const char* key, std::size_t size) {
    return system.with_scene([&](const sim::Scene& sc) {
      const auto it = sc.truth.find(key);
      if (it == sc.truth.end() || it->second.size() != size)
        throw std::runtime_error(
            fmt::format("scene '{}': truth entry '{}' with {} number(s) is missing", scene, key, size));
      return it->second;
    });
  };
  const auto c = truth("cylinder_centre_m", 2);
  centre_world_ = Eigen::Vector2d(c[0], c[1]);
  radius_m_ = truth("cylinder_radius_m", 1)[0];
  height_m_ = truth("sensing_height_m", 1)[0];
}

void SimulatedHydrus::place(const RobotPose2D& pose) {
  const Kinematics k = model_->forward(pose.joints_rad);
  const Eigen::Isometry2d Twb = pose.T_world_base();
  for (std::size_t s = 0; s < sensors_.size(); ++s) {
    const Eigen::Isometry2d T = Twb * k.T_base_sensor[s];
    system_->set_sensor_pose(
        sensors_[s], sim::planar_sensor_frame(T.translation(), Eigen::Rotation2Dd(T.linear()).angle(), height_m_,
                                              model_->sensors()[s].line_axis_left));
  }
  for (std::size_t l = 0; l < links_.size(); ++l) {
    const Eigen::Isometry2d T = Twb * k.T_base_link[l];
    const Eigen::Vector2d c = T * Eigen::Vector2d(0.5 * model_->links()[l].length_m, 0.0);
    Eigen::Isometry3d box = Eigen::Isometry3d::Identity();
    box.linear() =
        Eigen::AngleAxisd(Eigen::Rotation2Dd(T.linear()).angle(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    box.translation() = Eigen::Vector3d(c.x(), c.y(), height_m_);
    system_->set_object_pose(links_[l], box);
  }
}

}  // namespace tinyline::hydrus_fitting
