// SPDX-License-Identifier: Apache-2.0
// Picking pose and laser verification geometry (thesis 4.4, Figure 4.10):
// where the hand goes so that the tiny laser on it scans across the expected
// pedicel with the scissors' throat on it, and what a pedicel finder's answer
// at that pose means for the cut.
//
// The hand laser's frame is the sensor's: z forward along the optical axis,
// x along the laser line, y = z x x. The line sweeps the laser's x-z plane;
// the blade throat sits at (0, 0, throat_z_m) in it (laser_clustering's
// ScissorGeometry), the blades cutting along +z. At the picking pose the
// laser's y axis lies along the expected pedicel (the line cuts across it),
// its z axis points from the robot's side towards the cut (level, as far as
// the pedicel allows), and the throat sits on the planned cut point.
//
// The pedicel finder (laser_clustering, a separate package) looks at the
// scan; its answer comes back here as plain numbers (FinderAnswer) so that
// this core does not depend on it.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning {

/// The blades' swept volume in the throat frame (origin at the throat, z
/// along the blades, x across the opening, y through the blade layers): the
/// simulator's cutter model (sim::BladeParams) mirrored here, since the core
/// depends on no simulator, plus a margin for the vision's error.
struct BladeBox {
  double opening_m = 0.02;     ///< across the throat [m]
  double reach_m = 0.02;       ///< along the blades, either side of the throat [m]
  double thickness_m = 0.004;  ///< through the two blade layers [m]
  double margin_m = 0.004;     ///< every reconstructed fruit stays this far outside the box [m]
};

struct PickPoseParams {
  double throat_z_m = 0.12;  ///< blade throat along the laser's optical axis [m] (laser_clustering ScissorGeometry)
  /// Where the robot comes from, in the reference frame (e.g. the camera or
  /// the shoulder): the laser looks from this side towards the cut.
  Eigen::Vector3d approach_from{0, 0, 0};
  /// A move longer than this is not trusted [m]: the vision is rarely that
  /// far off (Table 4.3 tried offsets up to 5 cm), so the finder has chosen
  /// another pedicel or a stem; the verification then says nothing found.
  double max_move_m = 0.05;
  /// The laser's view of the throat along its scan plane must clear the
  /// other tomatoes by this much [m]: the pose may turn about the pedicel, by
  /// up to max_turn_deg from the straight approach, to see past a fruit in
  /// front (0: always the straight approach).
  double view_clearance_m = 0.01;
  double max_turn_deg = 60.0;
  BladeBox blades;
  /// Where along the pedicel a cut may go: this far beyond the fruit's
  /// surface [m], the first preferred. Nearer the calyx keeps the blades off
  /// the peduncle (the jams left were on it; the sepals are soft); further,
  /// off a neighbour. Tuned on tuning trusses (8, 5, 12, 16 mm before).
  std::vector<double> cut_offsets_m{0.004, 0.002, 0.006, 0.009};
  double roll_step_deg = 15.0;  ///< the blades' roll about the pedicel is tried in these steps, up to max_turn_deg
};

struct PickPose {
  int tomato = -1;  ///< index into PipelineResult::tomatoes
  Eigen::Isometry3d T_ref_laser = Eigen::Isometry3d::Identity();
  Eigen::Vector3d cut_point = Eigen::Vector3d::Zero();      ///< reference frame [m]
  Eigen::Vector3d pedicel_axis = Eigen::Vector3d::UnitZ();  ///< expected pedicel direction (unit)
  std::string reason;                                       ///< why there is no pose (tomato index out of range)
  [[nodiscard]] bool ok() const { return tomato >= 0; }
};

/// The picking pose for tomato `index` of a pipeline result (its cut plan),
/// turned about the pedicel when a fruit of the result blocks the view.
[[nodiscard]] PickPose picking_pose(const PipelineResult& result, int index, const PickPoseParams& params = {});
/// The same from a cut point and pedicel direction (the straight approach).
[[nodiscard]] PickPose picking_pose(const Eigen::Vector3d& cut_point, const Eigen::Vector3d& pedicel_axis,
                                    const PickPoseParams& params = {});
/// ... turned about the pedicel when one of `fruit` blocks the view.
[[nodiscard]] PickPose picking_pose(const Eigen::Vector3d& cut_point, const Eigen::Vector3d& pedicel_axis,
                                    const std::vector<Sphere>& fruit, const PickPoseParams& params = {});

/// The pose turned by `roll_rad` about its pedicel, the throat kept on its cut point.
[[nodiscard]] PickPose rolled(const PickPose& pose, double roll_rad, double throat_z_m);

/// How far the sphere lies outside the blade box at `T_ref_laser` [m]
/// (negative: it reaches into the blades).
[[nodiscard]] double blade_clearance(const Eigen::Isometry3d& T_ref_laser, const Sphere& s, const PickPoseParams& p);

/// One way to cut a pedicel: where along it, with what roll, and what the
/// blades and the laser's view clear.
struct CutCandidate {
  PickPose pose;
  double offset_m = 0.0;       ///< cut point beyond the fruit's surface along the pedicel [m]
  double roll_rad = 0.0;       ///< turn about the pedicel from the straight approach
  double blade_clear_m = 0.0;  ///< the nearest reconstructed fruit's distance outside the blade box [m]
  double view_clear_m = 0.0;   ///< ... from the laser's view of the throat [m]
  [[nodiscard]] bool fits(const PickPoseParams& p) const { return blade_clear_m >= p.blades.margin_m; }
};

/// Every cut of `target`'s pedicel along `pedicel_dir` (unit, from the centre
/// outwards) the parameters allow, best first: the blades clear of every
/// fruit (the target's own included) by the margin, then the laser's view
/// clear, then the smallest roll, then the preferred cut offset. When none
/// fits, the first is the one that clears most: check fits() before closing.
[[nodiscard]] std::vector<CutCandidate> cut_candidates(const Sphere& target, const Eigen::Vector3d& pedicel_dir,
                                                       const std::vector<Sphere>& others,
                                                       const PickPoseParams& params = {});
/// The same for tomato `index` of a result along its cut plan's direction,
/// among the fruit not `gone` (indices of result.tomatoes already picked).
[[nodiscard]] std::vector<CutCandidate> cut_candidates(const PipelineResult& result, int index,
                                                       const std::vector<int>& gone, const PickPoseParams& params = {});

/// Where else the blades may close on a pedicel the laser has put them on,
/// when the checks refuse that pose: the scan plane (the blade plane) moved
/// along the pedicel (near the calyx the sepals make it wide; near the
/// anchor the peduncle lies beside it) and the blades rolled about it (a
/// neighbour in the box).
struct CutProbeParams {
  /// Moves of the throat along the pedicel, + away from the fruit [m].
  std::vector<double> shifts_m{0.0, 0.004, -0.003, 0.008, -0.006};
  std::vector<double> rolls_deg{0.0, 20.0, -20.0, 40.0, -40.0};  ///< turns about the pedicel [deg]
  double shift_scale_m = 0.004;  ///< a move of this much ranks as far as a turn of roll_scale_deg
  double roll_scale_deg = 20.0;
};

/// The poses near `at` (its throat moved along its pedicel axis, turned
/// about it; `at` itself left out) whose blade box clears `others` by the
/// margin and `own` (the target's fruit, which follows the same pedicel) by
/// 1 mm, the smallest change first.
[[nodiscard]] std::vector<PickPose> nearby_cuts(const PickPose& at, const Sphere& own,
                                                const std::vector<Sphere>& others, const PickPoseParams& params = {},
                                                const CutProbeParams& probe = {});

/// What the pedicel finder said about the scan at the picking pose (laser
/// frame offsets, as laser_clustering::PedicelDetection gives them).
struct FinderAnswer {
  enum class Outcome { kCutHere, kMove, kNothingToCut, kOutOfView, kInvalidInput };
  Outcome outcome = Outcome::kInvalidInput;
  double lateral_offset_m = 0.0;  ///< gripper move along laser x that centres the pedicel [m]
  double depth_offset_m = 0.0;    ///< ... along laser z [m]
  double pedicel_x_m = 0.0;       ///< the pedicel found, laser frame [m]
  double pedicel_z_m = 0.0;
  double confidence = 0.0;
  std::string reason;
};

/// The verification's decision (thesis 4.4: cut here, move by this much, or nothing found).
struct Verification {
  enum class Outcome { kCutHere, kMove, kNothingFound, kOutOfView, kFailed };
  Outcome outcome = Outcome::kFailed;
  Eigen::Vector3d move = Eigen::Vector3d::Zero();       ///< gripper translation, reference frame [m]
  Eigen::Vector3d cut_point = Eigen::Vector3d::Zero();  ///< where the blades will meet, reference frame [m]
  Eigen::Isometry3d T_ref_laser_final = Eigen::Isometry3d::Identity();  ///< the pose after the move
  double confidence = 0.0;
  std::string reason;
  [[nodiscard]] bool will_cut() const { return outcome == Outcome::kCutHere || outcome == Outcome::kMove; }
};
[[nodiscard]] const char* to_string(Verification::Outcome o);

[[nodiscard]] Verification verify(const PickPose& pose, const FinderAnswer& answer, const PickPoseParams& params = {});

}  // namespace tinyline::tomato_reasoning
