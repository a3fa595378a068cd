// SPDX-License-Identifier: Apache-2.0
// The robot description's Hydrus inside a simulated scene: finds the
// description's sensors and links among the scene's sensors and objects by
// name and moves them to a robot pose, so the simulator measures from where
// the description says the sensors are. Used by the hydrus_sim node and the
// simulator study (hydrus_fitting/eval/sim_study).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <hydrus_fitting/robot_model.hpp>
#include <hydrus_fitting/trajectory.hpp>
#include <sim/system.hpp>

namespace tinyline::hydrus_fitting {

class SimulatedHydrus {
 public:
  /// Throws std::runtime_error naming the scene and what is missing: a sensor
  /// or link of the description not in the scene, or the truth entries
  /// cylinder_centre_m, cylinder_radius_m, sensing_height_m.
  SimulatedHydrus(sim::SimulatedSystem& system, const RobotModel& model);

  /// Moves every sensor and link box of the description to `pose` (base in
  /// the world, joint angles).
  void place(const RobotPose2D& pose);

  [[nodiscard]] std::size_t sim_sensor(std::size_t description_sensor) const { return sensors_.at(description_sensor); }
  [[nodiscard]] const Eigen::Vector2d& cylinder_centre_world_m() const { return centre_world_; }
  [[nodiscard]] double cylinder_radius_m() const { return radius_m_; }
  [[nodiscard]] double sensing_height_m() const { return height_m_; }
  /// The cylinder's centre in the robot (base) frame at `pose`.
  [[nodiscard]] Eigen::Vector2d centre_in_base(const RobotPose2D& pose) const {
    return pose.T_world_base().inverse() * centre_world_;
  }

 private:
  sim::SimulatedSystem* system_;
  const RobotModel* model_;
  std::vector<std::size_t> sensors_;
  std::vector<sim::ObjectId> links_;
  Eigen::Vector2d centre_world_ = Eigen::Vector2d::Zero();
  double radius_m_ = 0.0, height_m_ = 0.0;
};

}  // namespace tinyline::hydrus_fitting
