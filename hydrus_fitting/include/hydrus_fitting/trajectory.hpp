// SPDX-License-Identifier: Apache-2.0
// The grasp manoeuvre of thesis 6.2.3 (Figures 6.10, 6.11 B) as a planned
// motion: the robot flies in with its links open, stops beside the object,
// and closes its links around it. Piecewise linear in the base pose and the
// joint angles; what the simulator plays and the evaluation scores against.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <tinyline/common/status.hpp>

namespace tinyline::hydrus_fitting {

struct RobotPose2D {
  Eigen::Vector2d base_xy_m = Eigen::Vector2d::Zero();  ///< link1's frame in the world
  double base_yaw_rad = 0.0;
  std::vector<double> joints_rad;
  [[nodiscard]] Eigen::Isometry2d T_world_base() const;
};

struct ApproachParams {
  int joints = 3;
  /// Where the base stops (world): with 0.5 m links and 60 deg joints the
  /// chain is 4 sides of a hexagon whose centre (0.25, 0.433) in the base
  /// frame is then the world origin (the cylinder's axis in the scene).
  Eigen::Vector2d grasp_base_xy_m{-0.25, -0.4330127018922193};
  double base_yaw_rad = 0.0;
  Eigen::Vector2d approach_direction{0.0, 1.0};  ///< direction of flight (world, normalised on use)
  double start_distance_m = 0.75;                ///< the base starts this far before the grasp point
  double open_joint_rad = 0.3490658503988659;    ///< 20 deg while flying in
  /// 60 deg around the object: the sensors end 28 cm from a 10 cm radius
  /// cylinder, inside the sensor's characterised range (Table 3.1: 20-125 cm);
  /// closer, the simulated 3.6 mm sensor saturates at its shortest read-out.
  double closed_joint_rad = 1.0471975511965976;
  double approach_s = 6.0;
  double close_s = 4.0;
  double hold_s = 2.0;
  /// Why the parameters are impossible (InvalidArgument); ok when fine.
  common::Status validate() const;
  [[nodiscard]] double duration_s() const { return approach_s + close_s + hold_s; }
};

/// The pose at time t [s] from the start (clamped to [0, duration]).
[[nodiscard]] RobotPose2D approach_pose(const ApproachParams& p, double t_s);

}  // namespace tinyline::hydrus_fitting
