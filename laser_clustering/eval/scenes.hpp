// SPDX-License-Identifier: Apache-2.0
// Scenes of the laser_clustering evaluation (docs/laser_clustering.md),
// built on the simulator's world (sim/world.hpp) from a seed, with their
// ground truth:
//   - tomato trusses at the harvesting gripper (thesis 4.5, Table 4.3): the
//     simulator's close-up truss (sim/scenes/truss_close.hpp: pedicels as
//     thin rods, tomatoes as spheres hanging from them, the truss stem,
//     neighbouring pedicels and tomatoes, leaves behind), with the gripper
//     where the case puts it and what the vision expects;
//   - a metal stick a few millimetres before a panel (Figure 5.8 B);
//   - a wrench hanging on a panel, for the pitch sweep of 5.3.2.
//
// Frames: the world frame is the gripper laser's nominal observation pose:
// z forward, x along the laser line, y = z cross x (down). T_world_sensor is
// where the sensor really is (identity unless the case moves it).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include <sim/scenes/truss_close.hpp>
#include <sim/world.hpp>

#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/tomato_registration.hpp"

namespace tinyline::laser_clustering::eval {

/// The two cases of Table 4.3.
enum class TrussCase {
  /// The gripper's throat is where the vision put the pedicel; the real
  /// pedicel is off by a random horizontal offset under 5 cm.
  kRandomOffset,
  /// The vision found the tomato but got its pedicel's position and direction
  /// wrong: the gripper stands off by more and is turned; the expected pedicel
  /// position comes from the (correct) tomato.
  kRecognitionError,
};

/// The truss (the simulator's close-up truss: tilts, sizes, neighbours,
/// leaves, stem bow) and the gripper's and the vision's part.
struct TrussOptions : sim::CloseTrussParams {
  double throat_z_m = 0.15;    ///< blade throat ahead of the laser [m] (gripper geometry)
  double max_offset_m = 0.05;  ///< kRandomOffset: horizontal offset, uniform in a disc [m]
  /// kRecognitionError: the gripper's error (offset in a disc, yaw) and the
  /// error of the tomato-based expectation.
  double recognition_offset_m[2] = {0.02, 0.06};
  double recognition_yaw_deg = 30.0;
  double tomato_estimate_sd_m = 0.005;
  double tomato_radius_sd_m = 0.002;  ///< the vision's error on a tomato's radius [m]
  /// The vision expects a neighbour's pedicel in the laser plane when its
  /// tomato's top is at least this far below the plane, maybe there when
  /// less, and not at all when the tomato's top reaches this far above [m].
  double expected_pedicel_clearance_m = 0.015;
  double expected_tomato_in_plane_m = 0.005;
};

struct TrussTruth {
  sim::ObjectId target_pedicel = sim::kNoObject;
  std::vector<sim::ObjectId> pedicels;  ///< target first
  std::vector<sim::ObjectId> tomatoes;  ///< target's first
  sim::ObjectId stem = sim::kNoObject;  ///< the first rod of the stem chain (named stem0, stem1, ...)
  /// Where the target pedicel's axis crosses the sensor's laser plane, in the
  /// sensor frame [m] (the point the throat must reach).
  Eigen::Vector3d target_in_sensor = Eigen::Vector3d::Zero();
  double target_radius_m = 0.0;
  /// The expectation handed to the finder (kRecognitionError: from the
  /// tomato estimate, in the sensor frame; kRandomOffset: the throat).
  Eigen::Vector2d expected_xz_m = Eigen::Vector2d::Zero();
  double expected_sd_m = 0.0;
  bool use_expectation = false;
  /// The truss's other pedicels where the vision expects them (above each
  /// tomato it detected, 5 mm noise), in the sensor frame, moved with the
  /// vision's error: kRandomOffset puts the target's expectation on the
  /// throat and the neighbours where the vision's layout puts them from
  /// there. Drawn from their own random stream: the scenes do not change.
  std::vector<PedicelExpectation::Neighbour> neighbours_expected;
  /// Every tomato where the vision sees it (the same estimates as the
  /// layout's, target's first), in the sensor frame and moved with the same
  /// error, with its radius estimate (tomato_radius_sd_m): what a scan
  /// through the tomatoes is registered against (register_tomatoes).
  std::vector<ExpectedTomato> tomatoes_expected;
};

struct TrussScene {
  sim::World world;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  TrussTruth truth;
};

[[nodiscard]] TrussScene make_truss_scene(TrussCase c, std::uint64_t seed, const TrussOptions& o = {});

/// Sets a scene option from text (the evaluation's --scene-set key=value):
/// max_tilt_deg (0-60), stem_bow_m (-0.1-0.1). Returns why not, empty when set.
[[nodiscard]] std::string set_truss_option(TrussOptions& o, const std::string& key, const std::string& value);

struct StickOptions {
  double panel_distance_m[2] = {0.25, 0.35};
  double front_gap_m = 0.004;  ///< the stick's front face before the panel [m]
  double stick_width_m = 0.012;
  double stick_thickness_m = 0.003;
  double lateral_m = 0.04;                   ///< stick centre within +- this of the axis [m]
  double max_tilt_deg = 4.0;                 ///< stick and panel each tilted up to this
  const char* stick_material = "metal_pan";  ///< brushed (broad lobe); "metal_wrench" is polished
  const char* panel_material = "cardboard";
};

struct StickScene {
  sim::World world;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  sim::ObjectId stick = sim::kNoObject;
  sim::ObjectId panel = sim::kNoObject;
};

[[nodiscard]] StickScene make_stick_scene(std::uint64_t seed, const StickOptions& o = {});

struct WrenchOptions {
  double panel_distance_m[2] = {0.20, 0.30};
  double wrench_size_m[3] = {0.022, 0.18, 0.006};  ///< width (x), length (y), thickness
  double lateral_m = 0.03;
  double max_face_pitch_deg = 8.0;  ///< the hanging wrench's face is pitched up to this
  double max_face_yaw_deg = 3.0;
  double pivot_behind_m = 0.10;  ///< the gripper pitches about an axis this far behind the laser
  const char* wrench_material = "metal_wrench";
  const char* panel_material = "panel_grey";
};

struct WrenchScene {
  sim::World world;
  sim::ObjectId wrench = sim::kNoObject;
  /// The gripper pitch [rad] at which the laser's optical axis is square to
  /// the wrench face (in the plane the pitch moves it in).
  double true_pitch_rad = 0.0;
  /// Sensor pose at a gripper pitch [rad] (rotation about the laser's x axis
  /// around the pivot).
  [[nodiscard]] Eigen::Isometry3d T_world_sensor(double pitch_rad) const;
  double pivot_behind_m = 0.1;
};

[[nodiscard]] WrenchScene make_wrench_scene(std::uint64_t seed, const WrenchOptions& o = {});

}  // namespace tinyline::laser_clustering::eval
