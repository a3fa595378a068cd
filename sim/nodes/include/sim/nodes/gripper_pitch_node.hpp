// SPDX-License-Identifier: Apache-2.0
// A gripper pitch joint for the simulator: it carries a scene's tiny TOF
// sensor, so that the pitch sweep of 5.3.2 runs end to end on simulated scans
// (launch/wrench_align.launch.yaml, as laser_clustering/sim_gripper_pitch).
// Not an algorithm: the robot's arm controller stands here on a real robot.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Geometry>

#include <sim/system.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>

namespace tinyline::sim::nodes {

/// joint_command (sensor_msgs/JointState, the pitch_joint's position) ->
/// the scene sensor's pose: rotated about its own x axis (along the pixel
/// line) around a pivot pivot_behind_m behind it, by mount_pitch_deg plus
/// the joint's pitch; joint_states at rate_hz. The move is immediate (the
/// next set sees it): the sweep's dwell covers what a real arm's travel takes.
class SimGripperPitchNode : public bus::Node {
 public:
  explicit SimGripperPitchNode(bus::NodeOptions options);
  void on_start() override;
  /// The sensor pose at a joint pitch [rad].
  [[nodiscard]] Eigen::Isometry3d sensor_pose(double pitch_rad) const;

 private:
  void on_command(const sensor_msgs::msg::JointState& m);
  void publish_state();
  std::string scene_path_, sensor_name_, joint_;
  double pivot_behind_m_ = 0.0, mount_pitch_rad_ = 0.0, pitch_rad_ = 0.0;
  double min_pitch_rad_ = 0.0, max_pitch_rad_ = 0.0, rate_hz_ = 0.0;
  std::shared_ptr<SimulatedSystem> system_;
  std::size_t sensor_ = 0;
  Eigen::Isometry3d T_base_ = Eigen::Isometry3d::Identity();  // the scene's sensor pose
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::JointState>> state_pub_;
  std::shared_ptr<bus::Subscription<sensor_msgs::msg::JointState>> command_sub_;
  std::shared_ptr<bus::Timer> timer_;
};

}  // namespace tinyline::sim::nodes
