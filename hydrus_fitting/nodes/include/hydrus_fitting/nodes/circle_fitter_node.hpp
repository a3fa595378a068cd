// SPDX-License-Identifier: Apache-2.0
// circle_fitter: the whole-body object estimate of thesis 6.2.2-6.2.3 as a
// node. Every sensor's calibrated scans arrive on one topic (`scans`, their
// header.frame_id names the sensor in the robot description), the joint
// angles on `joint_states`; after each scan the latest scan of every sensor is
// fused at its own timestamp, the robot's own links are filtered out, and a
// robust circle is fitted (CircleEstimator). Publishes `circle`
// (tinyline_msgs/CircleFit) and `markers` (visualization_msgs/MarkerArray:
// the fitted cylinder, the fused points, the robot's links).
//
// Optional `base_pose` (geometry_msgs/PoseStamped: the base in a fixed frame,
// e.g. odometry): once poses arrive, each scan is moved by the base's own
// motion to the newest scan's time before fusing (the robot flies up to
// 1.5 cm during one update).
//
// The robot description is read in on_start() (a bad file stops the launch
// with its file, line and field).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/tinyline_msgs/circle_fit.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/visualization_msgs/marker_array.hpp>

#include "hydrus_fitting/estimator.hpp"
#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting {

class CircleFitterNode : public bus::Node {
 public:
  explicit CircleFitterNode(bus::NodeOptions options);
  void on_start() override;

  /// Scans received from sensors the description does not have, by name.
  [[nodiscard]] const std::map<std::string, std::uint64_t>& unknown_sensors() const { return unknown_; }

 private:
  struct LatestScan {
    std::int64_t stamp_ns = 0;
    std::vector<double> angle, range;
  };
  void on_scan(const tinyline_msgs::msg::LineScan& m);
  void on_joints(const sensor_msgs::msg::JointState& m);
  void on_base_pose(const geometry_msgs::msg::PoseStamped& m);
  void publish(const CircleEstimate& e);

  std::string description_path_;
  std::string frame_id_;
  double joint_tolerance_s_ = 0.0;
  double joint_history_s_ = 0.0;
  double base_pose_tolerance_s_ = 0.0;
  double base_pose_history_s_ = 0.0;
  double marker_height_m_ = 0.0;
  bool publish_points_ = true;
  CircleEstimatorParams params_;

  std::unique_ptr<RobotModel> model_;
  std::unique_ptr<JointStateBuffer> joints_;
  std::unique_ptr<BasePoseBuffer> base_poses_;
  std::unique_ptr<CircleEstimator> estimator_;
  std::vector<std::optional<LatestScan>> latest_;  // per sensor of the description
  std::map<std::string, std::uint64_t> unknown_;
  std::string last_joint_warning_;
  std::string last_base_warning_;

  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::CircleFit>> circle_pub_;
  std::shared_ptr<bus::Publisher<visualization_msgs::msg::MarkerArray>> marker_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> scan_sub_;
  std::shared_ptr<bus::Subscription<sensor_msgs::msg::JointState>> joint_sub_;
  std::shared_ptr<bus::Subscription<geometry_msgs::msg::PoseStamped>> base_pose_sub_;
};

}  // namespace tinyline::hydrus_fitting
