// SPDX-License-Identifier: Apache-2.0
// Pedicel finder (thesis 4.4.2, 4.5): from the objects of a two-stage
// clustering, the one whose width and range fit the pedicel prior (about
// 6 mm wide, as the thesis measured), and the move that
// centres it between the scissor blades (opening 2 cm, tomato.scissor_opening_m).
//
// Frames: everything is in the laser frame (z forward along the optical axis,
// x along the line). The blade throat (where the blades meet the pedicel) is
// at ScissorGeometry::centre_{x,z}_m, cutting along +z.
//
// "Nothing to cut here" and "out of view" are outcomes, not failures: the
// thesis's robot entered its laser-guide mode on the first (4.5) and counted
// the second as a trial lost to the field of view (Table 4.3).
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/two_stage.hpp"

namespace tinyline::laser_clustering {

struct ScissorGeometry {
  double centre_x_m = 0.0;   ///< blade throat along the line [m]
  double centre_z_m = 0.12;  ///< blade throat along the optical axis [m]
  double opening_m = 0.02;   ///< gap between the open blades [m] (the thesis's scissors)
};

struct PedicelFinderParams {
  double diameter_m = 0.006;  ///< pedicel prior [m] (the thesis's pedicel diameter)
  /// Spread of a measured width around the prior [m]: pixel footprint,
  /// mixed edge pixels and real pedicels together.
  double diameter_sd_m = 0.0025;
  double min_width_m = 0.002;  ///< narrower objects are never pedicels [m]
  double max_width_m = 0.014;  ///< wider objects (stems, tomatoes, leaves) are never pedicels [m]
  int min_points = 2;          ///< fewer points cannot show a width
  double min_range_m = 0.05;   ///< working range of the gripper [m]; nearer returns are ignored
  double max_range_m = 0.35;   ///< farther returns are background [m]
  /// Spread of where the pedicel is believed to be around the expected point
  /// (the blade throat unless the caller gives one) [m]; it ranks candidates.
  double search_sd_m = 0.03;
  /// A pedicel whose centre is within opening/2 - margin of the throat's line
  /// is already between the blades [m].
  double blade_margin_m = 0.004;
  /// ... and within this of the throat's depth (the blades are long) [m].
  double depth_tolerance_m = 0.015;
  /// Truss layout (PedicelExpectation::neighbours): the factor for an
  /// expected neighbour that falls in view with no pedicel near it (occluded
  /// by a tomato, missed), and for a pedicel-like object that no expected
  /// pedicel explains (a tomato edge, a pedicel the vision did not see).
  double layout_miss_factor = 0.25;
  double layout_extra_factor = 0.3;
  /// An expected pedicel behind a return this much nearer on its bearing is
  /// hidden, not missing [m].
  double occlusion_margin_m = 0.02;
  /// After the gripper centred a pedicel (expectation_after_centring): how
  /// far it may still be from the throat, the measurement's error rather than
  /// the vision's [m].
  double recentre_sd_m = 0.01;
  /// A thin dark object reads this much farther than its axis (the driver's
  /// calibration is fitted on white paper; a pedicel's front surface and its
  /// material differ): every object's centre is moved this much back along
  /// its bearing [m]. 0: none; measured on a pedicel-like rod.
  double range_bias_m = 0.0;
  ScissorGeometry scissors;
};

common::Validation validate(const PedicelFinderParams& params);

/// Where the caller expects the pedicel (e.g. projected from the vision
/// system's tomato and pedicel estimate), overriding the blade throat.
struct PedicelExpectation {
  Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();
  double sd_m = 0.03;  ///< how far off it may be [m]
  /// The truss's other pedicels where the vision expects them, in the same
  /// frame (e.g. above each detected tomato, thesis 4.4.1). The vision's
  /// estimate may be off as a whole by one offset (its error and the arm's,
  /// Table 4.3's "random offset"), but the layout of the truss moves with it:
  /// each candidate taken for the target shifts the layout onto itself, and a
  /// neighbour that is nearer the expected point than the target then fails
  /// to explain where the others are. Empty: position alone ranks candidates.
  struct Neighbour {
    Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();
    /// Its tomato reaches near the laser plane: the pedicel may cross the
    /// plane or not, so it explains a candidate but is never missed.
    bool may_be_absent = false;
  };
  std::vector<Neighbour> neighbours;
  double neighbour_sd_m = 0.015;  ///< error of a neighbour's place relative to the target's [m]
  /// Other places the pedicel may be, each with its weight relative to
  /// position_xz_m's (in (0, 1]), within sd_m too (e.g. the previous scan's
  /// runners-up, expectation_after_centring).
  struct Alternative {
    Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();
    double weight = 1.0;
  };
  std::vector<Alternative> alternatives{};
  /// A candidate farther than gate_sd x sd_m from position_xz_m (and from
  /// every alternative) is not the pedicel looked for; with none nearer the
  /// outcome is kNothingToCut (nothing to cut where the pedicel should be),
  /// not a move to whatever else is in view. Infinity: no gate. An
  /// expectation fixed by register_tomatoes is sure enough to set one.
  double gate_sd = std::numeric_limits<double>::infinity();
};

enum class PedicelOutcome {
  kCutHere,       ///< a pedicel is already between the blades (a small correction is still given)
  kMove,          ///< a pedicel is in view elsewhere: move by the offset (or turn by the angle)
  kNothingToCut,  ///< objects in range, none pedicel-like
  kOutOfView,     ///< nothing in the working range, or the only pedicel-like object is cut by the view's edge
  kInvalidInput,  ///< bad parameters or a malformed scan (see reason)
};
[[nodiscard]] const char* to_string(PedicelOutcome o);

struct PedicelCandidate {
  int cluster = -1;  ///< index into TwoStageResult::clusters
  double width_m = 0.0;
  Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();
  double shape_score = 0.0;     ///< width fit to the prior, in (0, 1]
  double isolation = 0.0;       ///< 1 free on both sides, 0.5 per occluded side
  double position_score = 0.0;  ///< closeness to the expected point, in (0, 1]
  /// How well the expected truss layout, shifted onto this candidate, meets
  /// the other candidates (1 without a layout), in (0, 1].
  double layout_score = 1.0;
  double weight = 0.0;  ///< product of the four
};

struct PedicelDetection {
  PedicelOutcome outcome = PedicelOutcome::kInvalidInput;
  std::string reason;
  int cluster = -1;                                         ///< the chosen object (index into clusters), -1 if none
  Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();  ///< its centre, laser frame [m]
  double width_m = 0.0;
  /// Translation of the gripper (laser frame) that puts the pedicel in the
  /// blade throat: lateral along x, depth along z [m].
  double lateral_offset_m = 0.0;
  double depth_offset_m = 0.0;
  /// Or: yaw about the laser origin that brings the pedicel onto the line
  /// from the origin through the throat [rad], positive towards +x.
  double angle_rad = 0.0;
  /// How sure: the chosen candidate's shape and isolation times its share of
  /// all candidates' weight (an ambiguous scene lowers it), in [0, 1].
  double confidence = 0.0;
  std::vector<PedicelCandidate> candidates;  ///< every candidate considered, best first
};

/// `e` with every place it holds (the expected point, the neighbours, the
/// alternatives) moved by `by` in the plane [m]: the vision's offset found
/// by register_tomatoes, or minus a move of the gripper.
[[nodiscard]] PedicelExpectation shifted(PedicelExpectation e, const Eigen::Vector2d& by);

/// The closed loop of thesis 4.5 (move, scan again, re-centre): what to
/// expect in the next scan once the gripper has made a detection's move. The
/// chosen pedicel is then expected in the blade throat, within
/// `params.recentre_sd_m`, and the truss layout of `before` (if any) moves
/// with it, keeping each neighbour where it was relative to the expected
/// pedicel. Without `before` the expected pedicel was the throat itself.
[[nodiscard]] PedicelExpectation expectation_after_centring(const PedicelFinderParams& params,
                                                            const std::optional<PedicelExpectation>& before);
/// The same, carrying `moved`'s runners-up along as `alternatives`: each
/// where the move put it, weighted by its weight over the chosen one's. The
/// next scan, from elsewhere, may see the pedicel that tells them apart, and
/// its layout can then overturn the choice (one more scan re-centres).
[[nodiscard]] PedicelExpectation expectation_after_centring(const PedicelFinderParams& params,
                                                            const std::optional<PedicelExpectation>& before,
                                                            const PedicelDetection& moved);

/// The gripper moved by `move_xz_m` (laser frame: lateral x, depth z)
/// without centring anything, e.g. backed off to widen the view: every
/// candidate of `seen` is expected where the move put it, the chosen one as
/// `position_xz_m` within `params.recentre_sd_m` and the runners-up as
/// `alternatives` with their weights over the chosen one's; the layout of
/// `before` (if any) moves with the chosen one. expectation_after_centring
/// with a detection is this with the move that centres the chosen pedicel.
[[nodiscard]] PedicelExpectation expectation_after_move(const PedicelFinderParams& params,
                                                        const std::optional<PedicelExpectation>& before,
                                                        const PedicelDetection& seen, const Eigen::Vector2d& move_xz_m);

/// Picks the pedicel among `objects` (from the same scan). `expectation`
/// replaces the blade throat as the expected position when given.
[[nodiscard]] PedicelDetection find_pedicel(const LineScan& scan, const TwoStageResult& objects,
                                            const PedicelFinderParams& params,
                                            const std::optional<PedicelExpectation>& expectation = std::nullopt);

}  // namespace tinyline::laser_clustering
