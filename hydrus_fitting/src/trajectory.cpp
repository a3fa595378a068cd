// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/trajectory.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

Eigen::Isometry2d RobotPose2D::T_world_base() const {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.translation() = base_xy_m;
  T.linear() = Eigen::Rotation2Dd(base_yaw_rad).toRotationMatrix();
  return T;
}

common::Status ApproachParams::validate() const {
  if (joints < 0) return common::Status::invalid(fmt::format("joints must be >= 0, got {}", joints));
  if (!grasp_base_xy_m.allFinite() || !std::isfinite(base_yaw_rad))
    return common::Status::invalid("grasp pose must be finite");
  if (!(approach_direction.norm() > 0.0) || !approach_direction.allFinite())
    return common::Status::invalid("approach_direction must be a non-zero finite vector");
  if (!(start_distance_m >= 0.0))
    return common::Status::invalid(fmt::format("start_distance_m must be >= 0, got {}", start_distance_m));
  if (!std::isfinite(open_joint_rad) || !std::isfinite(closed_joint_rad))
    return common::Status::invalid("joint angles must be finite");
  if (!(approach_s >= 0.0) || !(close_s >= 0.0) || !(hold_s >= 0.0))
    return common::Status::invalid(
        fmt::format("phase durations must be >= 0 s, got approach {} close {} hold {}", approach_s, close_s, hold_s));
  return common::Status{};
}

RobotPose2D approach_pose(const ApproachParams& p, double t_s) {
  RobotPose2D pose;
  pose.base_yaw_rad = p.base_yaw_rad;
  const double t = std::clamp(std::isfinite(t_s) ? t_s : 0.0, 0.0, p.duration_s());
  // Phase 1: fly in along the approach direction with the links open.
  const double a = p.approach_s > 0.0 ? std::min(1.0, t / p.approach_s) : 1.0;
  const Eigen::Vector2d dir = p.approach_direction.normalized();
  pose.base_xy_m = p.grasp_base_xy_m - (1.0 - a) * p.start_distance_m * dir;
  // Phase 2: close the links; phase 3: hold.
  const double c =
      p.close_s > 0.0 ? std::clamp((t - p.approach_s) / p.close_s, 0.0, 1.0) : (t >= p.approach_s ? 1.0 : 0.0);
  pose.joints_rad.assign(static_cast<std::size_t>(std::max(0, p.joints)),
                         p.open_joint_rad + c * (p.closed_joint_rad - p.open_joint_rad));
  return pose;
}

}  // namespace tinyline::hydrus_fitting
