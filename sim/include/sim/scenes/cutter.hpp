// SPDX-License-Identifier: Apache-2.0
// The harvesting scissors of the thesis's hand (4.2.2, Figure 4.3) closing
// in a simulated truss: what the blades meet, and whether the fruit falls.
//
// The throat frame: origin at the blade throat (where a pedicel sits when the
// scissors are on it), z along the blades (the hand laser's optical axis: the
// hand pushes along +z), x across the opening (the laser line), y normal to
// the blade plane (along the pedicel when the pose is right). It is the hand
// laser's frame moved throat_z along z (throat_from_laser()).
//
// Closing sweeps a box in that frame: |x| <= opening/2 across, |z| <= reach
// along, |y| <= thickness/2 through the two blade layers (one cuts, one holds).
// That box is the verification's "on the pedicel" test (the pedicel within half
// the 2 cm opening across and within 2 cm along the blades) given a thickness,
// so a throat the verification calls aligned cuts unless something else is in
// the way. The box is sampled every `grid_m`; every solid of the truss that
// occupies a sample is in the blades:
//   - pedicels (rods anchor -> calyx of the truss's pedicel radius) are cut
//     when their diameters together are within what the blades can sever;
//   - a fruit, the peduncle or the main stem stops the blades: jammed, a cut
//     failure (Table 4.2's CF).
// Sepals and leaves are soft and thin: the blades go through them.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/scenes/truss.hpp>
#include <sim/world.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

struct BladeParams {
  /// Throat opening across the blades [m]: the thesis's scissors open 2 cm
  /// (4.4, "as the scissor opens only 2[cm], it can not hold the stem"); the
  /// verification holds a pedicel within half of it of the throat.
  double opening_m = 0.02;
  /// How far along the blades, either side of the throat, they close on what
  /// lies between them [m]: the verification's "within 2 cm along the blades".
  double reach_m = 0.02;
  /// Thickness of the two blade layers (cutting and holding, 4.2.2) across
  /// the blade plane [m]. The thesis gives no figure; scissors' blades are a
  /// few millimetres thick.
  double thickness_m = 0.004;
  /// Total diameter of pedicel the blades sever in one closing [m]. 4.2.2:
  /// the finger gives 163.5 N against the 137.3 N an average pedicel needs
  /// (a 19% margin, and about 10% of cuts still failed), so the blades sever
  /// one pedicel (the truss's are 6 mm, as the thesis's 0.6 cm in 4.4) but
  /// not two at once, nor the 9 mm peduncle or the stem.
  double max_cut_diameter_m = 0.007;
  /// Sampling step of the blade box [m]: finer than half a pedicel.
  double grid_m = 0.001;

  common::Status validate() const;
};

enum class CutResult {
  kCutTarget,        ///< the target's pedicel was severed: its fruit falls (a pick)
  kCutOtherPedicel,  ///< another tomato's pedicel was severed (that fruit falls)
  kClosedOnNothing,  ///< the blades met no pedicel
  kJammed,           ///< the blades met fruit, peduncle, stem or more pedicel than they sever: a cut failure
};
[[nodiscard]] const char* to_string(CutResult r);

struct CutOutcome {
  CutResult result = CutResult::kClosedOnNothing;
  int tomato = -1;           ///< whose pedicel was severed (the target's when it is among them), -1 none
  std::vector<int> severed;  ///< every tomato whose pedicel was severed (their fruit fall)
  std::string object;        ///< what stopped the blades (kJammed), e.g. "fruit 2", "peduncle", "main stem"
};

/// Closes the blades at T_world_throat on the truss's geometry (pedicel
/// segments anchor -> calyx, fruit shapes, peduncle polyline, main stem).
/// `target` is the tomato being picked (index into truss.tomatoes): with
/// -1 a severed pedicel reports kCutTarget and `tomato` says whose.
/// Two pedicels in the throat: both are in the blades, and their diameters
/// add up; with the defaults (6 mm pedicels, 7 mm capacity) that jams
/// ("pedicels 1 and 3") and nothing is cut.
/// Invalid parameters give kJammed with the reason as the object.
[[nodiscard]] CutOutcome close_blades(const Truss& truss, const Eigen::Isometry3d& T_world_throat,
                                      const BladeParams& params, int target = -1);

/// The throat frame of a hand laser (its frame moved throat_z_m along z).
[[nodiscard]] Eigen::Isometry3d throat_from_laser(const Eigen::Isometry3d& T_world_laser, double throat_z_m);

/// The main stem as add_to_world() places it (axis end points, radius).
struct StemRod {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero(), p1 = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};
[[nodiscard]] StemRod main_stem(const Truss& truss);

/// Where a fallen fruit goes: this far below where it hung [m].
inline constexpr double kFallenDrop_m = 100.0;

/// The fruit falls when its pedicel is cut: tomato `i` (fruit, pedicel) drops
/// kFallenDrop_m in the truss's record, so close_blades no longer meets it.
/// Throws std::out_of_range for a bad index.
void drop_tomato(Truss& truss, int i);
/// ... and its objects in a world built by add_to_world(truss, world)
/// (fruit patches, pedicel, sepals), so cameras and lasers no longer see it.
/// Returns how many objects moved (0: already gone or not in this world).
int drop_tomato(World& world, const Truss& truss, int i);
/// True when tomato `i` has fallen (drop_tomato on the truss).
[[nodiscard]] bool dropped(const Truss& truss, int i);

}  // namespace tinyline::sim
