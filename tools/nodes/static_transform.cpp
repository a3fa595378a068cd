// SPDX-License-Identifier: Apache-2.0
// tf2_ros/static_transform_publisher: one fixed frame on /tf_static, the way
// ROS 2's node of that name declares it in a launch file:
//
//   - node:
//       pkg: tf2_ros
//       exec: static_transform_publisher
//       args: "--x 0 --y 0 --z 0.05 --yaw 1.5708 --frame-id base_link --child-frame-id laser"
//
// Its parameters are ROS 2's flags (x y z in m; roll pitch yaw in rad, or qx
// qy qz qw; frame_id, child_frame_id). The message is latched (transient
// local) and published once at start, as ROS 2's static broadcaster does.
#include <array>
#include <cmath>
#include <initializer_list>

#include <fmt/format.h>

#include <tinyline/msg/tf2_msgs/tf_message.hpp>
#include <tinyline/tools/nodes.hpp>

namespace tinyline::tools {

namespace {

using Quaternion = std::array<double, 4>;  // x, y, z, w

/// Roll about x, then pitch about y, then yaw about z (ROS 2's RPY convention).
Quaternion from_rpy(double roll, double pitch, double yaw) {
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2);
  const double cp = std::cos(pitch / 2), sp = std::sin(pitch / 2);
  const double cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  return {sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
          cr * cp * cy + sr * sp * sy};
}

class StaticTransformPublisher : public bus::Node {
 public:
  explicit StaticTransformPublisher(bus::NodeOptions o) : Node(std::move(o)) {
    auto m = std::make_unique<geometry_msgs::msg::TransformStamped>();
    declare_frames(*m);
    declare_pose(*m);
    check_frames(*m);
    // Depth 100: every static transform publisher of a process shares one
    // DDS writer for /tf_static, and a late joiner must get each one's frame.
    pub_ = create_publisher<tf2_msgs::msg::TFMessage>("/tf_static", bus::QoS::keep_last(100).latched());
    transform_ = std::move(m);
  }

  void on_start() override {
    auto msg = std::make_unique<tf2_msgs::msg::TFMessage>();
    msg->transforms.push_back(*transform_);
    msg->transforms.back().header.stamp = now().to_msg();
    pub_->publish(std::move(msg));
  }

 private:
  void declare_frames(geometry_msgs::msg::TransformStamped& m) {
    bus::ParamConstraints required;
    required.required = true;
    m.header.frame_id = declare_parameter<std::string>("frame_id", "", "parent frame", required);
    m.child_frame_id = declare_parameter<std::string>("child_frame_id", "", "child frame", required);
  }

  void declare_pose(geometry_msgs::msg::TransformStamped& m) {
    auto& t = m.transform;
    t.translation.x = declare_parameter("x", 0.0, "translation along the parent's x [m]");
    t.translation.y = declare_parameter("y", 0.0, "translation along the parent's y [m]");
    t.translation.z = declare_parameter("z", 0.0, "translation along the parent's z [m]");
    const Quaternion rpy = from_rpy(declare_parameter("roll", 0.0, "rotation about x [rad]"),
                                    declare_parameter("pitch", 0.0, "rotation about y [rad]"),
                                    declare_parameter("yaw", 0.0, "rotation about z [rad]"));
    const Quaternion q{declare_parameter("qx", 0.0, "rotation quaternion x (instead of roll, pitch, yaw)"),
                       declare_parameter("qy", 0.0, "rotation quaternion y"),
                       declare_parameter("qz", 0.0, "rotation quaternion z"),
                       declare_parameter("qw", 1.0, "rotation quaternion w")};
    const bool quaternion = any_set({"qx", "qy", "qz", "qw"});
    if (quaternion && any_set({"roll", "pitch", "yaw"})) {
      throw bus::ParamError(where("qw"), fmt::format("node '{}': give the rotation as roll, pitch, yaw or as qx, qy, "
                                                     "qz, qw, not both",
                                                     full_name()));
    }
    Quaternion r = quaternion ? q : rpy;
    const double norm = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    if (!(norm > 1e-9) || !std::isfinite(norm)) {
      throw bus::ParamError(where("qw"), fmt::format("node '{}': the quaternion ({}, {}, {}, {}) has no direction",
                                                     full_name(), q[0], q[1], q[2], q[3]));
    }
    for (double& c : r) c /= norm;
    t.rotation.x = r[0], t.rotation.y = r[1], t.rotation.z = r[2], t.rotation.w = r[3];
  }

  // Both frames are required parameters: a missing one is refused where they are declared.
  void check_frames(const geometry_msgs::msg::TransformStamped& m) const {
    if (!m.header.frame_id.empty() && m.header.frame_id == m.child_frame_id) {
      throw bus::ParamError(where("child_frame_id"), fmt::format("node '{}': frame '{}' cannot be its own parent",
                                                                 full_name(), m.child_frame_id));
    }
  }

  /// Where the launch file (or command line) set this parameter; if it did
  /// not, where it set any (the `args` line), so an error points there.
  bus::SourceLocation where(const std::string& name) const {
    bus::SourceLocation any;
    for (const auto& d : parameters()) {
      if (d.name == name && d.set_from.known()) return d.set_from;
      if (!any.known()) any = d.set_from;
    }
    return any;
  }

  bool any_set(std::initializer_list<const char*> names) const {
    for (const auto& d : parameters())
      for (const char* n : names)
        if (d.name == n && d.set_from.known()) return true;
    return false;
  }

  std::unique_ptr<geometry_msgs::msg::TransformStamped> transform_;
  std::shared_ptr<bus::Publisher<tf2_msgs::msg::TFMessage>> pub_;
};

}  // namespace

void register_static_transform(bus::NodeRegistry& r) {
  r.add<StaticTransformPublisher>("tf2_ros", "static_transform_publisher",
                                  "publishes one fixed frame on /tf_static (latched), as ROS 2's node of that name");
}

}  // namespace tinyline::tools
