// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/nodes/rgbd_folder_camera.hpp"

#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include <tinyline/msg/eigen.hpp>

#include "tomato_reasoning/nodes/nodes.hpp"

namespace tinyline::tomato_reasoning::nodes {

using bus::ParamConstraints;

namespace {

/// The camera's pose from the two parameters; throws ParamError naming the bad one.
Eigen::Isometry3d camera_pose(const bus::Node& n, const std::vector<double>& p, const std::vector<double>& q) {
  const std::string who = "node '" + n.full_name() + "': ";
  if (p.size() != 3)
    throw bus::ParamError({}, who + "position_m needs 3 numbers (x, y, z), got " + std::to_string(p.size()));
  if (q.size() != 4)
    throw bus::ParamError({}, who + "orientation_xyzw needs 4 numbers (x, y, z, w), got " + std::to_string(q.size()));
  const Eigen::Quaterniond rot(q[3], q[0], q[1], q[2]);
  // Not normalised silently: a quaternion far from unit length is a typing error.
  if (!rot.coeffs().allFinite() || std::abs(rot.norm() - 1.0) > 1e-3)
    throw bus::ParamError({}, who + "orientation_xyzw is not a unit quaternion");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rot.normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
  return T;
}

}  // namespace

RgbdFolderCameraNode::RgbdFolderCameraNode(bus::NodeOptions o) : Node(std::move(o)) {
  ParamConstraints required;
  required.required = true;
  folder_ = declare_parameter<std::string>(
      "folder", "", "folder of RGB-D frames: intrinsics.yaml, rgb/NAME.png|jpg, depth/NAME.png (16-bit)", required);
  ParamConstraints rate = ParamConstraints::range(0.01, 100.0), metres;
  rate.unit = "Hz";
  metres.unit = "m";
  rate_hz_ = declare_parameter("rate_hz", 1.0, "frames per second", rate);
  loop_ = declare_parameter("loop", false, "start again at the first frame after the last");
  frame_id_ =
      declare_parameter<std::string>("frame_id", "camera", "the camera's optical frame (x right, y down, z forward)");
  pose_frame_id_ = declare_parameter<std::string>(
      "pose_frame_id", "",
      "frame the camera's pose is given in; set: publish `pose` with every frame (empty: no pose)");
  const auto p = declare_parameter<std::vector<double>>("position_m", {0.0, 0.0, 0.0},
                                                        "camera origin in pose_frame_id: x, y, z", metres);
  const auto q = declare_parameter<std::vector<double>>(
      "orientation_xyzw", {0.0, 0.0, 0.0, 1.0}, "camera orientation in pose_frame_id: unit quaternion x, y, z, w");
  T_parent_camera_ = camera_pose(*this, p, q);
  cloud_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud");
  played_pub_ = create_publisher<std_msgs::msg::String>("played", bus::QoS::keep_last(1).latched());
  if (!pose_frame_id_.empty()) pose_pub_ = create_publisher<geometry_msgs::msg::PoseStamped>("pose");
}

void RgbdFolderCameraNode::on_configure() {
  // The executor names the node; the errors name the file.
  frames_ = io::open_folder(folder_);  // refuses a folder without frames
}

void RgbdFolderCameraNode::on_start() {
  const auto& k = frames_.intrinsics;
  logger().info("{}: {} frame(s), {} x {} px, fx {:.1f} fy {:.1f}, {} at {} Hz", folder_, frames_.frames.size(),
                k.width, k.height, k.fx, k.fy, loop_ ? "looped" : "once", rate_hz_);
  // The first frame one period after start: every node (the recorder too) is listening by then.
  timer_ = create_timer(std::chrono::nanoseconds(std::int64_t(1e9 / rate_hz_)), [this] { tick(); });
}

void RgbdFolderCameraNode::tick() {
  if (next_ >= frames_.frames.size()) {
    if (loop_) {
      next_ = 0;
    } else {
      // One period after the last frame: the detector has had it.
      timer_->cancel();
      auto done = std::make_unique<std_msgs::msg::String>();
      done->data = fmt::format("{}: played {} frame(s), skipped {}", folder_, played_, skipped_);
      logger().info("{}", done->data);
      played_pub_->publish(std::move(done));
      return;
    }
  }
  if (publish_frame(frames_.frames[next_]))
    ++played_;
  else
    ++skipped_;
  ++next_;
}

bool RgbdFolderCameraNode::publish_frame(const io::FrameFiles& f) {
  auto c = std::make_unique<sensor_msgs::msg::PointCloud2>();
  try {
    to_msg(io::read_frame(f, frames_.intrinsics), *c);
  } catch (const io::RgbdFileError& e) {
    logger().warn("skipping frame {}: {}", f.name, e.what());
    return false;
  }
  c->header.stamp = now().to_msg();
  c->header.frame_id = frame_id_;
  if (pose_pub_) {
    auto pose = std::make_unique<geometry_msgs::msg::PoseStamped>();
    pose->header.stamp = c->header.stamp;
    pose->header.frame_id = pose_frame_id_;
    pose->pose = tinyline::msg::to_pose(T_parent_camera_);
    pose_pub_->publish(std::move(pose));
  }
  logger().debug("frame {} ({})", f.name, f.colour);
  cloud_pub_->publish(std::move(c));
  return true;
}

}  // namespace tinyline::tomato_reasoning::nodes
