// SPDX-License-Identifier: Apache-2.0
// Conversions between the geometry messages and Eigen, as ROS 2's tf2_eigen
// offers them: header-only, for nodes (which already use Eigen); the message
// structs themselves stay free of it.
#pragma once

#include <Eigen/Geometry>

#include <tinyline/msg/geometry_msgs/point.hpp>
#include <tinyline/msg/geometry_msgs/pose.hpp>

namespace tinyline::msg {

inline geometry_msgs::msg::Point to_point(const Eigen::Vector3d& p) {
  geometry_msgs::msg::Point m;
  m.x = p.x();
  m.y = p.y();
  m.z = p.z();
  return m;
}

inline geometry_msgs::msg::Pose to_pose(const Eigen::Isometry3d& T) {
  geometry_msgs::msg::Pose p;
  p.position = to_point(T.translation());
  const Eigen::Quaterniond q(T.linear());
  p.orientation.x = q.x();
  p.orientation.y = q.y();
  p.orientation.z = q.z();
  p.orientation.w = q.w();
  return p;
}

/// The pose as a transform; the quaternion is normalised (a caller that must
/// reject a non-unit or non-finite one checks the message first).
inline Eigen::Isometry3d to_isometry(const geometry_msgs::msg::Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
                   .normalized()
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

}  // namespace tinyline::msg
