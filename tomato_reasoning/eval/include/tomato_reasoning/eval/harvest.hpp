// SPDX-License-Identifier: Apache-2.0
// Harvest trials like the thesis's Table 4.2 (4.5), end to end on simulated
// trusses: the truss is harvested in the pipeline's pick order; at each
// detected tomato the hand goes to the picking pose, the laser verification
// (with its closed loop, as configured) places the blade throat, and the
// blades close (sim's cutter model: which object they meet). A fruit whose
// pedicel is cut falls and leaves the world before the next scan. When the
// first attempt does not pick the fruit, the hand scans again from where it
// is and tries once more (the thesis's second attempt); after two, the fruit
// is left for a human.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/scenes/cutter.hpp>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/verification.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::eval {

/// How one trial (a true tomato the harvest sets out to pick) ended, as
/// Table 4.2 counts it.
enum class HarvestOutcome {
  kPickedFirst,   ///< SP(1): its pedicel cut on the first attempt
  kPickedSecond,  ///< SP(2): ... on a later attempt, after the laser's re-scan from where the last left the hand
  kLeftForHuman,  ///< HS: not picked after the attempts (or never detected, or no picking pose)
  kCutFailure,    ///< CF: the blades jammed on fruit, peduncle, stem or two pedicels
  kKnockedOff,    ///< its pedicel was cut by an attempt at another tomato: it fell, not picked
};
[[nodiscard]] const char* to_string(HarvestOutcome o);

struct HarvestTrial {
  char complexity = 'B';
  std::uint64_t seed = 0;
  int truth = -1;         ///< the true tomato (index into the truss)
  bool detected = false;  ///< SD: a sphere of the pipeline matched it
  int pick_rank = -1;     ///< its place in the pick order (-1: not attempted)
  int attempts = 0;       ///< attempts made at it
  int scans = 0;          ///< laser scans over its attempts
  HarvestOutcome outcome = HarvestOutcome::kLeftForHuman;
  std::string
      cuts;  ///< each attempt's end, ';'-separated: sim::to_string(CutResult), or "no cut" (the verification refused)
  std::string jammed_on;  ///< what stopped the blades (kCutFailure)
  /// Why each attempt that did not close did not, ';'-separated ("" for one
  /// that closed): "no cut clears the blades", the verification's reason, or
  /// what the blades' check saw.
  std::string why;
  /// Each attempt that closed at a nearby cut rather than the loop's final
  /// pose, ';'-separated: its move along the pedicel and roll ("+4mm 20deg").
  std::string probed;
  /// Per attempt, ';'-separated, whether the blade throat lay on the true
  /// pedicel (throat_on_pedicel) at the vision's planned cut (v), at the
  /// laser loop's final pose (l) and where the blades closed (c): "v1l0c1"
  /// ('-': no such pose). A score of the arbitration, never read by the harvest.
  std::string on_pedicel;
};

/// The blades closing at a throat pose on the truss as it now hangs
/// (`target`: the tomato picked). Default: sim::close_blades.
using CutModel =
    std::function<sim::CutOutcome(const sim::Truss& truss, const Eigen::Isometry3d& T_world_throat, int target)>;

struct HarvestOptions {
  int attempts = 2;  ///< the thesis's: a second try, then human support
  /// The attempts after the first go towards a pedicel the finder sees
  /// beyond max_move_m (VerificationOptions::approach_far), the blades'
  /// checks below deciding whether to close there: the thesis's "laser
  /// guide mode" when nothing is found where the pedicel should be.
  bool later_attempts_approach_far = true;
  /// Before closing, the blades' box at the final pose must clear every
  /// reconstructed fruit (PickPoseParams::blades) and the laser, scanning in
  /// the blade plane, must see one thin object and nothing else there; else
  /// the attempt refuses and the next one comes from another pose.
  bool check_blades = true;
  /// When the checks refuse the loop's final pose, up to this many nearby
  /// cuts on the same pedicel (moved along it, rolled: nearby_cuts) are
  /// checked by the laser, every check of the final pose's repeated there
  /// (blade_plane_shifts_m too), and the blades close at the first that
  /// passes (0: refuse at once). 4 on tuning trusses 201-240 and 1-40 (with
  /// the planes beside): picked +4 points, cut failures not up; without the
  /// planes beside, the probes' cuts jammed on the peduncle.
  int probes = 4;
  CutProbeParams probe;  ///< where the nearby cuts are
  /// Probe also when the laser refused (two objects, a wide one, nothing),
  /// not only when a reconstructed fruit is in the box.
  bool probe_after_laser_refusal = true;
  /// The vision's cut against the laser's: when the loop moved the cut more
  /// than arbitrate_mm from the vision's planned cut, the laser first checks
  /// the blades at the vision's cut (one scan) and they close there when it
  /// sees one thin object in the box and the box clears the reconstructed
  /// fruit (both agree); else the loop's final pose is checked as before.
  /// Negative: off (on tuning trusses 6 mm picked 1 point more and jammed
  /// about as much more).
  double arbitrate_mm = -1.0;
  /// When the loop finds nothing (or nothing within the move limit), the
  /// laser still checks the vision's cut and the blades close there when it
  /// sees one thin object in the box.
  bool vision_when_nothing = false;
  /// Blade planes beside the scan plane checked before closing [m] (laser
  /// y, along the pedicel): the blades are 4 mm thick, and a peduncle or
  /// fruit within their thickness but off the single scan plane jams them.
  /// A second object or a wide one in any of these planes refuses the cut
  /// (one scan each; tuning trusses 201-240: cut failures 6.1 -> 3.2 %).
  std::vector<double> blade_plane_shifts_m{-0.002, 0.002};
  /// Each attempt's loop is given the truss as the camera reconstructed it
  /// (truss_view): the look through the tomatoes and the pedicel search
  /// (the sweep of the blade plane, turned sweeps) run before the closed
  /// loop, as in Table 4.3's verification. Off: on tuning trusses it picked
  /// no more and jammed more (turned sweeps find neighbours' pedicels).
  bool pedicel_search = false;
  /// The hand laser subtracts the pedicel range bias measured on a rod
  /// (VerificationOptions::pedicel_range_bias_m) in the harvest's scans too.
  /// Off: on tuning trusses it raised cut failures by 2-3 points (more jams
  /// on the peduncle) and picked no more.
  bool rod_range_bias = false;
  /// When no cut along the pedicel hypothesis fits the blades, the planner
  /// tries the hypothesis tilted by these angles [deg] (six sides each, the
  /// smallest tilt first): the estimated direction is some 10-30 deg off,
  /// and the laser's loop and the checks before closing decide from there.
  /// Empty (default): say "no cut clears the blades" at once. On tuning
  /// trusses 201-240, 15 and 30 deg picked 6 more and jammed 4 more.
  std::vector<double> no_cut_tilts_deg;
  /// The world's ceiling: the truth's pedicel (calyx -> anchor) handed to the
  /// planner and the cutter model as its clearance check; a trial is picked
  /// when some cut along it (offset, roll) severs it and nothing else.
  bool ceiling = false;
  sim::BladeParams blades;  ///< the default cut model's scissors
  double match_m = 0.01;    ///< a detection is a true tomato when its centre is this near [m]
};

/// Sets one option by name (attempts, later_attempts_approach_far=0|1,
/// check_blades=0|1, probes=0..9, probe_after_laser_refusal=0|1,
/// probe_shifts_mm, probe_rolls_deg, arbitrate_mm (-1: off),
/// vision_when_nothing=0|1, blade_plane_shifts_mm (mm list or "none"),
/// pedicel_search=0|1, rod_range_bias=0|1, ceiling=0|1);
/// throws std::invalid_argument saying what is wrong.
void set_harvest_option(HarvestOptions& o, const std::string& key, const std::string& value);

/// The names set_harvest_option takes, for help and error texts.
inline constexpr const char* kHarvestOptionNames =
    "attempts, later_attempts_approach_far, check_blades, probes, probe_after_laser_refusal, probe_shifts_mm, "
    "probe_rolls_deg, arbitrate_mm, vision_when_nothing, blade_plane_shifts_mm, pedicel_search, rod_range_bias, "
    "no_cut_tilts_deg, ceiling";

/// The hand laser's options for the harvest: `vo` without the rod-measured
/// range bias unless o.rod_range_bias (a bias `vo` sets is kept).
[[nodiscard]] VerificationOptions harvest_laser(VerificationOptions vo, const HarvestOptions& o);

/// Harvests the truss of `s` as `r` (the pipeline's result on it) orders,
/// the hand laser of `laser` verifying each attempt. One trial per true
/// tomato, in the truss's order. `cut` replaces the cutter model (tests).
[[nodiscard]] std::vector<HarvestTrial> harvest(VerificationHarness& laser, const Scenario& s, const PipelineResult& r,
                                                const HarvestOptions& o = {}, const CutModel& cut = {});

/// Table 4.2's row of a set of trials.
struct HarvestCounts {
  int trials = 0, detected = 0, picked_first = 0, picked_second = 0, left_for_human = 0, cut_failures = 0,
      knocked_off = 0;
  void add(const HarvestTrial& t);
  HarvestCounts& operator+=(const HarvestCounts& o);
};

}  // namespace tinyline::tomato_reasoning::eval
