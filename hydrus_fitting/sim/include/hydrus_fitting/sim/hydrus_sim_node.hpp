// SPDX-License-Identifier: Apache-2.0
// hydrus_sim: flies the simulated Hydrus of a scene (sim/config/scenes/
// hydrus4_grasp.yaml) through the grasp manoeuvre (ApproachParams: fly in
// with the links open, close them around the cylinder, hold) and moves the
// scene's link boxes and sensors accordingly, in the process's shared
// SimulatedSystem for that scene file, so the drivers' in-process virtual
// devices (`port: sim:SCENE.yaml#laserN`) measure from where the links are.
//
//   joint_states  sensor_msgs/JointState   the joint angles (robot description's names), at rate_hz
//   truth         tinyline_msgs/CircleFit  the true cylinder in the robot frame (for scoring)
//   base_pose     geometry_msgs/PoseStamped  the base in the scene's fixed frame ("world"), as odometry
//
// Registered as hydrus_fitting/hydrus_sim (launch/hydrus_grasp.launch.yaml).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/tinyline_msgs/circle_fit.hpp>

#include <hydrus_fitting/robot_model.hpp>
#include <hydrus_fitting/trajectory.hpp>

namespace tinyline::sim {
class SimulatedSystem;
}  // namespace tinyline::sim

namespace tinyline::hydrus_fitting {
class SimulatedHydrus;
}  // namespace tinyline::hydrus_fitting

namespace tinyline::hydrus_fitting::sim_nodes {

class HydrusSimNode : public bus::Node {
 public:
  explicit HydrusSimNode(bus::NodeOptions options);
  ~HydrusSimNode() override;
  void on_start() override;

  /// Manoeuvre time of the last tick [s].
  [[nodiscard]] double manoeuvre_time_s() const { return last_t_; }

 private:
  void tick();

  std::string scene_path_, description_path_, frame_id_;
  double rate_hz_ = 100.0;
  bool loop_ = true;
  ApproachParams approach_;
  std::unique_ptr<RobotModel> model_;
  std::shared_ptr<sim::SimulatedSystem> system_;
  std::unique_ptr<SimulatedHydrus> robot_;
  bus::Time start_{};
  bool started_ = false;
  double last_t_ = 0.0;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::JointState>> joint_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::CircleFit>> truth_pub_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PoseStamped>> base_pose_pub_;
  std::shared_ptr<bus::Timer> timer_;
};

}  // namespace tinyline::hydrus_fitting::sim_nodes
