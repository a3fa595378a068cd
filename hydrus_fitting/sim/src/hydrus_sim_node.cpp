// SPDX-License-Identifier: Apache-2.0
#include <hydrus_fitting/sim/hydrus_sim_node.hpp>
#include <hydrus_fitting/sim/register.hpp>

#include <cmath>

#include <fmt/format.h>

#include <hydrus_fitting/sim/simulated_hydrus.hpp>
#include <sim/nodes/nodes.hpp>
#include <sim/system.hpp>
#include <tinyline/bus/param_table.hpp>
#include <tinyline/bus/registry.hpp>

#include <hydrus_fitting/param_tables.hpp>
#include <hydrus_fitting/robot_model.hpp>

namespace tinyline::hydrus_fitting::sim_nodes {

using bus::ParamConstraints;
namespace msgs = tinyline_msgs::msg;

HydrusSimNode::HydrusSimNode(bus::NodeOptions o) : Node(std::move(o)) {
  ParamConstraints scene = sim::nodes::scene_file();
  scene.required = true;
  scene_path_ = declare_parameter<std::string>(
      "scene", "", "scene YAML with the Hydrus (sim/config/scenes/hydrus4_grasp.yaml)", scene);
  ParamConstraints description = ParamConstraints::input_file(kMaxRobotDescriptionBytes);
  description.required = true;
  description_path_ = declare_parameter<std::string>(
      "robot_description", "", "robot description YAML (links, joints, sensor mounts)", description);
  frame_id_ = declare_parameter<std::string>("frame_id", "base", "frame of `truth`: the robot description's base");
  rate_hz_ = declare_parameter("rate_hz", 100.0, "joint states (and pose updates) per second",
                               ParamConstraints::range(1.0, 1000.0));
  loop_ = declare_parameter("loop", true, "start the manoeuvre again when it ends");
  bus::declare_params(*this, approach_);  // the table: hydrus_fitting/param_tables.hpp
  require_valid(approach_.validate());
  joint_pub_ = create_publisher<sensor_msgs::msg::JointState>("joint_states");
  truth_pub_ = create_publisher<msgs::CircleFit>("truth");
  base_pose_pub_ = create_publisher<geometry_msgs::msg::PoseStamped>("base_pose");
}

void HydrusSimNode::on_start() {
  // Bad files stop the launch here, naming file, line and field.
  model_ = std::make_unique<RobotModel>(RobotModel::load(description_path_));
  approach_.joints = static_cast<int>(model_->joint_names().size());
  // The same system as the drivers' `sim:` devices of this process.
  system_ = sim::SimulatedSystem::shared(scene_path_);
  robot_ = std::make_unique<SimulatedHydrus>(*system_, *model_);
  robot_->place(approach_pose(approach_, 0.0));
  logger().info("flying '{}' in scene '{}': {} s manoeuvre{}", model_->name(), system_->scene_name(),
                approach_.duration_s(), loop_ ? ", looped" : "");
  timer_ = create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz_)), [this] { tick(); });
}

HydrusSimNode::~HydrusSimNode() = default;

void HydrusSimNode::tick() {
  const bus::Time now_t = now();
  if (!started_) {
    start_ = now_t;
    started_ = true;
  }
  double t = (now_t.ns - start_.ns) * 1e-9;
  const double T = approach_.duration_s();
  if (loop_ && T > 0.0) t = std::fmod(t, T);
  last_t_ = t;
  const RobotPose2D pose = approach_pose(approach_, t);
  robot_->place(pose);

  auto js = std::make_unique<sensor_msgs::msg::JointState>();
  js->header.stamp = now_t.to_msg();
  js->header.frame_id = frame_id_;
  js->name = model_->joint_names();
  js->position = pose.joints_rad;
  joint_pub_->publish(std::move(js));

  // The base in the scene's fixed frame, as odometry would give it.
  auto bp = std::make_unique<geometry_msgs::msg::PoseStamped>();
  bp->header.stamp = now_t.to_msg();
  bp->header.frame_id = "world";
  bp->pose.position.x = pose.base_xy_m.x();
  bp->pose.position.y = pose.base_xy_m.y();
  bp->pose.position.z = model_->sensor_height_m();
  bp->pose.orientation.z = std::sin(0.5 * pose.base_yaw_rad);
  bp->pose.orientation.w = std::cos(0.5 * pose.base_yaw_rad);
  base_pose_pub_->publish(std::move(bp));

  auto truth = std::make_unique<msgs::CircleFit>();
  truth->header.stamp = now_t.to_msg();
  truth->header.frame_id = frame_id_;
  truth->status = msgs::CircleFit::STATUS_OK;
  const Eigen::Vector2d c = robot_->centre_in_base(pose);
  truth->centre.x = c.x();
  truth->centre.y = c.y();
  truth->centre.z = model_->sensor_height_m();
  truth->radius_m = robot_->cylinder_radius_m();
  truth->radius_known = true;
  truth_pub_->publish(std::move(truth));
}

}  // namespace tinyline::hydrus_fitting::sim_nodes

namespace tinyline::hydrus_fitting {

void register_sim_nodes(bus::NodeRegistry& r) {
  r.add<sim_nodes::HydrusSimNode>(
      "hydrus_fitting", "hydrus_sim",
      "flies the simulated Hydrus of a scene through the grasp: moves its links and sensors, "
      "publishes joint states and the true cylinder");
}

}  // namespace tinyline::hydrus_fitting
