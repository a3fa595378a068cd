// SPDX-License-Identifier: Apache-2.0
#include <sim/nodes/gripper_pitch_node.hpp>

#include "parts.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

namespace tinyline::sim::nodes {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
}

SimGripperPitchNode::SimGripperPitchNode(bus::NodeOptions o) : bus::Node(std::move(o)) {
  using bus::ParamConstraints;
  scene_path_ = declare_parameter<std::string>("scene", "",
                                               "scene YAML whose sensor the gripper carries [required]; "
                                               "the same path as the virtual_sensor's",
                                               scene_file());
  sensor_name_ = declare_parameter<std::string>("sensor", "", "sensor name in the scene; empty: the first");
  joint_ = declare_parameter<std::string>("pitch_joint", "gripper_pitch", "the joint's name in JointState");
  pivot_behind_m_ = declare_parameter("pivot_behind_m", 0.10, "the pitch axis lies this far behind the laser [m]",
                                      ParamConstraints::range(0.0, 2.0));
  mount_pitch_rad_ = kDeg * declare_parameter("mount_pitch_deg", 0.0,
                                              "the sensor's pitch at joint zero, relative to its scene pose [deg]",
                                              ParamConstraints::range(-90.0, 90.0));
  pitch_rad_ = kDeg * declare_parameter("initial_pitch_deg", 0.0, "joint pitch at start [deg]",
                                        ParamConstraints::range(-90.0, 90.0));
  min_pitch_rad_ =
      kDeg * declare_parameter("min_pitch_deg", -45.0, "joint limit [deg]", ParamConstraints::range(-90.0, 90.0));
  max_pitch_rad_ =
      kDeg * declare_parameter("max_pitch_deg", 45.0, "joint limit [deg]", ParamConstraints::range(-90.0, 90.0));
  rate_hz_ = declare_parameter("rate_hz", 100.0, "joint_states per second", ParamConstraints::range(1.0, 10000.0));
  if (!(max_pitch_rad_ > min_pitch_rad_)) {
    throw bus::ParamError({}, fmt::format("node '{}': max_pitch_deg must be above min_pitch_deg", full_name()));
  }
  state_pub_ = create_publisher<sensor_msgs::msg::JointState>("joint_states", bus::QoS::keep_last(50));
  command_sub_ = create_subscription<sensor_msgs::msg::JointState>(
      "joint_command", bus::QoS::keep_last(10), [this](const sensor_msgs::msg::JointState& m) { on_command(m); });
}

void SimGripperPitchNode::on_start() {
  if (scene_path_.empty()) throw bus::ParamError({}, "node '" + full_name() + "': parameter 'scene' is required");
  system_ = sim::SimulatedSystem::shared(scene_path_);
  if (system_->sensor_count() == 0) throw bus::ParamError({}, "node '" + full_name() + "': the scene has no sensor");
  sensor_ = sensor_name_.empty() ? 0 : system_->sensor_index(sensor_name_);
  T_base_ = system_->sensor_pose(sensor_);
  pitch_rad_ = std::clamp(pitch_rad_, min_pitch_rad_, max_pitch_rad_);
  system_->set_sensor_pose(sensor_, sensor_pose(pitch_rad_));
  timer_ =
      create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz_)), [this] { publish_state(); });
}

Eigen::Isometry3d SimGripperPitchNode::sensor_pose(double pitch_rad) const {
  Eigen::Isometry3d back = Eigen::Isometry3d::Identity(), rot = Eigen::Isometry3d::Identity();
  back.translation() = Eigen::Vector3d(0.0, 0.0, -pivot_behind_m_);
  rot.linear() = Eigen::AngleAxisd(mount_pitch_rad_ + pitch_rad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return T_base_ * back * rot * back.inverse();
}

void SimGripperPitchNode::on_command(const sensor_msgs::msg::JointState& m) {
  const auto it = std::find(m.name.begin(), m.name.end(), joint_);
  if (it == m.name.end()) return;
  const auto k = static_cast<std::size_t>(it - m.name.begin());
  if (k >= m.position.size() || !std::isfinite(m.position[k])) {
    logger().warn("joint_command for '{}' without a finite position: ignored", joint_);
    return;
  }
  const double p = std::clamp(m.position[k], min_pitch_rad_, max_pitch_rad_);
  if (p != m.position[k])
    logger().warn("'{}' command {:.2f} deg clamped to the joint limits", joint_, m.position[k] / kDeg);
  pitch_rad_ = p;
  if (system_) system_->set_sensor_pose(sensor_, sensor_pose(pitch_rad_));
  publish_state();
}

void SimGripperPitchNode::publish_state() {
  auto s = std::make_unique<sensor_msgs::msg::JointState>();
  s->header.stamp = now().to_msg();
  s->name = {joint_};
  s->position = {pitch_rad_};
  state_pub_->publish(std::move(s));
}

void register_gripper_nodes(bus::NodeRegistry& r) {
  r.add<SimGripperPitchNode>("laser_clustering", "sim_gripper_pitch",
                             "simulator only: a gripper pitch joint carrying a scene's sensor (joint_command -> "
                             "sensor pose, joint_states)");
}

}  // namespace tinyline::sim::nodes
