// SPDX-License-Identifier: Apache-2.0
// The multi-link aerial robot Hydrus (thesis 6.2, Figures 6.7-6.11) in the
// simulated world: a chain of flat links joined by yaw joints, flying level,
// with one tiny TOF line sensor per link, all at the height of the sensing
// plane, looking at the object the chain closes around.
//
// Planar kinematics, the same as hydrus_fitting's robot description
// (hydrus_fitting/config/hydrus4.yaml): link i's frame sits at its near
// joint with x along the link; link 1's frame is the robot's base; joint i
// turns link i+1 by q_i about z (positive curls the chain to the left).
// A sensor is mounted on its link at (x, y) with the optical axis at yaw;
// its 3-D frame is the sim's sensor frame: z along the optical axis, x along
// the line (to the left of the axis when line_axis_left), y = z cross x.
//
// Generator "hydrus" (scene YAML `generators:`) adds the links as boxes
// (`<name>link<i>`) and the sensors (`<name>laser<i>`):
//
//   - type: hydrus
//     links: 4
//     link_length_m: 0.5
//     link_width_m: 0.08
//     link_thickness_m: 0.04
//     height_m: 0.5                     # sensing plane above z = 0
//     base: {xy_m: [-0.9, -0.25], yaw_deg: 0}
//     joints_deg: [0, 0, 0]
//     sensor_mount_m: [0.25, 0.05]      # on each link, link frame
//     sensor_yaw_deg: 90
//     line_axis: left
//     sensor_config: ../sensors/tiny_tof_3p6mm.yaml
//     material: carbon_frame
//
// A node that flies the robot moves the boxes and sensors with
// hydrus_poses() (SimulatedSystem::set_object_pose / set_sensor_pose).
#pragma once

#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/scene.hpp>
#include <sim/sensor_params.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

struct HydrusChainParams {
  std::string name;  ///< prefix of object and sensor names ("" -> link1.., laser1..)
  int links = 4;
  double link_length_m = 0.5;
  double link_width_m = 0.08;
  double link_thickness_m = 0.04;              ///< box size along z
  double height_m = 0.5;                       ///< sensing plane (and link centre) above world z = 0
  Eigen::Vector2d sensor_mount_m{0.25, 0.05};  ///< sensor origin in its link's frame
  double sensor_yaw_rad = 1.5707963267948966;  ///< optical axis in the link frame
  bool line_axis_left = true;
  std::string material = "carbon_frame";

  [[nodiscard]] std::string link_name(int i) const { return name + "link" + std::to_string(i + 1); }
  [[nodiscard]] std::string sensor_name(int i) const { return name + "laser" + std::to_string(i + 1); }
  /// Why the parameters are impossible (InvalidArgument); ok when fine.
  common::Status validate() const;
};

/// Where the robot is: base pose in the plane and the links-1 joint angles.
struct HydrusState {
  Eigen::Vector2d base_xy_m = Eigen::Vector2d::Zero();
  double base_yaw_rad = 0.0;
  std::vector<double> joints_rad;
};

struct HydrusPoses {
  std::vector<Eigen::Isometry3d> T_world_link_box;  ///< box centres (world), one per link
  std::vector<Eigen::Isometry3d> T_world_sensor;    ///< sim sensor frames (world), one per link
  std::vector<Eigen::Isometry2d> T_world_link;      ///< planar link frames (near joint, x along the link)
};

/// Throws std::invalid_argument when joints_rad does not hold links-1 angles.
[[nodiscard]] HydrusPoses hydrus_poses(const HydrusChainParams& chain, const HydrusState& state);

/// The sim sensor frame of a planar sensor pose (origin, optical-axis yaw) at height z.
[[nodiscard]] Eigen::Isometry3d planar_sensor_frame(const Eigen::Vector2d& origin_m, double yaw_rad, double height_m,
                                                    bool line_axis_left);

/// Adds the chain's link boxes and its sensors (parameters `sensor`) to a
/// scene at `state`. Throws std::invalid_argument on bad parameters or a
/// sensor placed inside an object.
void add_hydrus(const HydrusChainParams& chain, const HydrusState& state, const SensorParams& sensor,
                const std::string& sensor_config_file, Scene& scene);

}  // namespace tinyline::sim
