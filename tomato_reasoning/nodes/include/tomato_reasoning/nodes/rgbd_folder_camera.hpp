// SPDX-License-Identifier: Apache-2.0
// rgbd_folder_camera  a folder of RGB-D frames played as a camera
//                     (tomato_reasoning/io/rgbd_files.hpp: intrinsics.yaml,
//                     rgb/NAME.png|jpg, depth/NAME.png, 16-bit): `cloud`
//                     (PointCloud2, organised XYZRGB in the camera's optical
//                     frame, as the simulated truss_camera publishes it) at
//                     rate_hz, in name order, once or in a loop; with
//                     `pose_frame_id` set also `pose` (PoseStamped: the
//                     camera in that frame, as given by position_m and
//                     orientation_xyzw), same stamp, published first.
//                     Played once, it says so one period after the last
//                     frame on `played` (String: frames played and skipped),
//                     so `tinyline launch ... --until /camera/played` ends
//                     when the detector has had the last frame.
//                     A frame that cannot be read is skipped with a warning
//                     naming its file; a folder that cannot be opened stops
//                     the launch.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include <Eigen/Geometry>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"

namespace tinyline::tomato_reasoning::nodes {

class RgbdFolderCameraNode : public bus::Node {
 public:
  explicit RgbdFolderCameraNode(bus::NodeOptions options);
  void on_configure() override;
  void on_start() override;

 private:
  void tick();
  bool publish_frame(const io::FrameFiles& f);
  std::string folder_, frame_id_, pose_frame_id_;
  double rate_hz_ = 1.0;
  bool loop_ = false;
  Eigen::Isometry3d T_parent_camera_ = Eigen::Isometry3d::Identity();
  io::RgbdFolder frames_;
  std::size_t next_ = 0, played_ = 0, skipped_ = 0;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::PointCloud2>> cloud_pub_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PoseStamped>> pose_pub_;
  std::shared_ptr<bus::Publisher<std_msgs::msg::String>> played_pub_;
  std::shared_ptr<bus::Timer> timer_;
};

}  // namespace tinyline::tomato_reasoning::nodes
