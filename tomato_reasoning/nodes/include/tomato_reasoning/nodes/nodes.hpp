// SPDX-License-Identifier: Apache-2.0
// Nodes of tomato_reasoning: thin shells that convert messages, call the
// core (pipeline.hpp, pick_pose.hpp) and publish.
//
// tomato_detector  cloud (sensor_msgs/PointCloud2, XYZ + RGB) -> tomatoes
//                  (tinyline_msgs/TomatoEstimates: spheres, pedicel
//                  estimates, pick order, cut plans) and markers
//                  (visualization_msgs/MarkerArray: spheres, pedicel arrows,
//                  contact edges, pick ranks) for Foxglove. With `views: 2`
//                  (the thesis's robot, 4.5) it fuses a second view: `cloud2`
//                  and `cloud2_pose` (PoseStamped: that camera's pose in
//                  `cloud`'s frame, as the kinematics and the hand-camera
//                  calibration give it); the three with the same stamp make
//                  one detection, in `cloud`'s frame.
// pick_verifier    tomatoes -> the harvest, tomato by tomato in pick order
//                  (thesis 4.4-4.5): the hand laser's picking pose
//                  (`pick_pose`, PoseStamped) and the expected pedicel in the
//                  laser's frame (`expected_pedicel`, for laser_clustering's
//                  pedicel_finder); the finder's answer (`pedicel`) ->
//                  `verification` (PickVerification: cut here, move by this
//                  much, or nothing found); then, as harvest.hpp decides, a
//                  re-scan after the move (`pick_pose` again), or closing the
//                  scissors (`cut`, CutCommand) and the gripper's report
//                  (`cut_outcome`, CutOutcome). When every detected tomato
//                  has had its pick: `summary` (HarvestSummary) and the
//                  per-pick outcomes in the log.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/point_stamped.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/tinyline_msgs/cut_command.hpp>
#include <tinyline/msg/tinyline_msgs/cut_outcome.hpp>
#include <tinyline/msg/tinyline_msgs/harvest_summary.hpp>
#include <tinyline/msg/tinyline_msgs/pedicel_detection.hpp>
#include <tinyline/msg/tinyline_msgs/pick_verification.hpp>
#include <tinyline/msg/tinyline_msgs/tomato_estimates.hpp>
#include <tinyline/msg/visualization_msgs/marker_array.hpp>

#include "tomato_reasoning/cloud.hpp"
#include "tomato_reasoning/harvest.hpp"
#include "tomato_reasoning/pick_pose.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::nodes {

/// PointCloud2 with float32 x, y, z and rgb (packed as PCL does, or as
/// uint32) -> ColorCloud; empty when fine, else what is wrong.
[[nodiscard]] std::string to_core(const sensor_msgs::msg::PointCloud2& m, ColorCloud& out);
/// ColorCloud -> PointCloud2 (x, y, z, rgb float32, organised when the cloud is).
void to_msg(const ColorCloud& c, sensor_msgs::msg::PointCloud2& out);
void to_msg(const PipelineResult& r, const Eigen::Vector3d& gravity, tinyline_msgs::msg::TomatoEstimates& out);
/// Spheres, expected pedicel arrows, contact edges and pick ranks.
void to_markers(const tinyline_msgs::msg::TomatoEstimates& t, visualization_msgs::msg::MarkerArray& out);

class TomatoDetectorNode : public bus::Node {
 public:
  explicit TomatoDetectorNode(bus::NodeOptions options);

 private:
  void on_cloud(const sensor_msgs::msg::PointCloud2& m);
  void on_cloud2(const sensor_msgs::msg::PointCloud2& m);
  void on_cloud2_pose(const geometry_msgs::msg::PoseStamped& m);
  void detect();  ///< when every view of one stamp is in
  void publish(std::unique_ptr<tinyline_msgs::msg::TomatoEstimates> out);
  std::unique_ptr<TomatoPipeline> pipeline_;
  int views_ = 1;
  // The latest of each input; a detection takes the three of one stamp.
  std::optional<std_msgs::msg::Header> header_, header2_, pose2_header_;
  std::string bad_;  ///< why the latest input cannot be used (empty: fine)
  ColorCloud cloud_, cloud2_;
  Eigen::Isometry3d T_ref_camera2_ = Eigen::Isometry3d::Identity();
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::TomatoEstimates>> pub_;
  std::shared_ptr<bus::Publisher<visualization_msgs::msg::MarkerArray>> markers_pub_;
  std::shared_ptr<bus::Subscription<sensor_msgs::msg::PointCloud2>> sub_, sub2_;
  std::shared_ptr<bus::Subscription<geometry_msgs::msg::PoseStamped>> pose2_sub_;
};

class PickVerifierNode : public bus::Node {
 public:
  explicit PickVerifierNode(bus::NodeOptions options);

 private:
  void on_tomatoes(const tinyline_msgs::msg::TomatoEstimates& m);
  void on_pedicel(const tinyline_msgs::msg::PedicelDetection& m);
  void on_cut_outcome(const tinyline_msgs::msg::CutOutcome& m);
  void next_pick();
  void scan();                        ///< at the current attempt's pose
  void act(const GripperStep& step);  ///< cut, re-scan, or end the pick
  void end_pick(PickOutcome outcome, const std::string& detail);
  void publish_verification(const Verification& v);
  void summary();
  PickPoseParams params_;
  HarvestParams harvest_;
  int max_picks_ = 0;
  std::optional<tinyline_msgs::msg::TomatoEstimates> estimates_;
  std::size_t rank_ = 0;
  enum class Waiting { kNothing, kScan, kCut };
  Waiting waiting_ = Waiting::kNothing;
  bool done_ = false;
  std::optional<PickAttempts> attempts_;
  std::vector<tinyline_msgs::msg::PickVerification> results_;
  std::vector<tinyline_msgs::msg::HarvestPick> picks_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PoseStamped>> pose_pub_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PointStamped>> expected_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::PickVerification>> result_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::CutCommand>> cut_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::HarvestSummary>> summary_pub_;
  std::shared_ptr<bus::Publisher<visualization_msgs::msg::MarkerArray>> markers_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::TomatoEstimates>> tomatoes_sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::PedicelDetection>> pedicel_sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::CutOutcome>> cut_sub_;
};

}  // namespace tinyline::tomato_reasoning::nodes
