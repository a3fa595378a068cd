// SPDX-License-Identifier: Apache-2.0
// The evaluation harness of docs/laser_clustering.md: seeded trials of the
// scenes in scenes.hpp, scanned by a Scanner (the simulated sensor and the
// driver's processing, see eval/scanner.hpp), scored against ground truth,
// with Wilson 95 % confidence intervals.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "scanner.hpp"
#include <sim/world.hpp>

#include "laser_clustering/alignment_search.hpp"
#include "laser_clustering/line_scan.hpp"
#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/reflectance_clustering.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "laser_clustering/two_stage.hpp"
#include "scenes.hpp"

namespace tinyline::laser_clustering::eval {

// The scanner: the simulated sensor and the driver's processing (eval/scanner.hpp).

/// A proportion with its Wilson score 95 % interval.
struct Rate {
  int k = 0, n = 0;
  double p = 0.0, lo = 0.0, hi = 0.0;
};
[[nodiscard]] Rate wilson(int k, int n);

// ---------------------------------------------------------------------------- trusses (Table 4.3)

enum class Verdict {
  kAligned,    ///< the move puts the target pedicel between the blades
  kWrong,      ///< the finder chose something else (a neighbour, a tomato edge) or misplaced the target
  kOutOfView,  ///< no move, and the target pedicel is not in the scan
  kMissed,     ///< no move although the target pedicel is in the scan
};
[[nodiscard]] const char* to_string(Verdict v);

struct TrussTrial {
  std::uint64_t seed = 0;
  Verdict verdict = Verdict::kOutOfView;
  PedicelOutcome outcome = PedicelOutcome::kInvalidInput;
  sim::ObjectId chosen = sim::kNoObject;  ///< majority ground-truth object of the chosen cluster
  std::string chosen_kind;                ///< "target", "pedicel", "tomato", "stem", "leaf", "none"
  double lateral_error_m = 0.0;           ///< target vs throat after the move (aligned/wrong with a move)
  double confidence = 0.0;
  bool target_visible = false;
  /// Another pedicel crosses the laser plane nearer the expected point (the
  /// throat, or the case's expectation) than the target: a finder that takes
  /// the nearest pedicel cannot be right (the thesis's "nearby pedicels").
  bool neighbour_nearer = false;
  int rescans = 0;          ///< scans after the first (TrussEvalOptions::rescans)
  bool looked = false;      ///< a look through the tomatoes was taken (TrussEvalOptions::tomato_look)
  bool registered = false;  ///< ... and registered the vision's tomatoes
};

/// "target", "pedicel", "tomato", "stem", "leaf" or "none" for a ground-truth object of a truss scene.
[[nodiscard]] std::string object_kind(const TrussScene& scene, sim::ObjectId id);

struct TrussResult {
  std::vector<TrussTrial> trials;
  Rate aligned, wrong, out_of_view, missed;
  Rate ambiguous;            ///< trials with neighbour_nearer
  Rate aligned_unambiguous;  ///< aligned among the others
};

struct TrussEvalOptions {
  TrussOptions scene;
  TwoStageParams clustering;
  PedicelFinderParams finder;  ///< its scissor throat is set from scene.throat_z_m
  /// The move succeeds when the target's axis ends within opening/2 minus
  /// its radius of the throat's line, and within this of the throat's depth.
  double depth_tolerance_m = 0.02;
  /// Hand the case's expectation (kRecognitionError: from the tomato) to the
  /// finder; false: the finder looks for the pedicel nearest the throat.
  bool use_expectation = true;
  /// Hand the vision's layout of the truss's other pedicels too
  /// (TrussTruth::neighbours_expected_xz_m; for kRandomOffset with the throat
  /// as the target's expectation); false: the target's expectation alone.
  bool use_layout = true;
  /// The closed loop of 4.5: after a move, up to this many further scans,
  /// each re-centring on the pedicel the finder sees in the throat
  /// (expectation_after_centring). 0: the first scan's move alone. Two: a
  /// re-scan may switch to a runner-up, and the next one re-centres on it.
  int rescans = 2;
  /// Each re-scan's expectation carries the previous scan's runners-up with
  /// their weights (expectation_after_centring with the detection); false:
  /// the chosen pedicel alone, the before of that change.
  bool carry_runners_up = true;
  /// The tomato look (docs/laser_clustering.md): before the first move the
  /// gripper lowers the laser plane to the target tomato's expected centre
  /// and backs off look_back_m (out of the sensor's short-range bias),
  /// registers the vision's tomatoes to that scan (register_tomatoes), and
  /// when that gives a clear shift, the target's expectation and the layout
  /// move by it (the target then expected within registered_sd_m, gated at
  /// registered_gate_sd) and the finder decides again on the first scan.
  /// false: no look, the before of it.
  bool tomato_look = true;
  double look_back_m = 0.08;
  double registered_sd_m = 0.012;
  double registered_gate_sd = 4.0;  ///< PedicelExpectation::gate_sd of a registered expectation
  /// When nothing pedicel-like lies within that gate, move the throat to the
  /// registered expectation and let the closed loop look from there.
  bool blind_move = true;
  TomatoRegistrationParams registration;
  /// The registration searches the common offset within this many of the
  /// expectation's sd (and registration.max_shift_m).
  double registration_search_sd = 3.0;
};

/// Runs `trials` seeded trials (seed0, seed0 + 1, ...). `on_trial` (optional)
/// sees every trial with its first scan and clustering, for pictures; the
/// verdict is the closed loop's.
using TrussObserver = std::function<void(const TrussTrial&, const TrussScene&, const SimulatedScan&,
                                         const TwoStageResult&, const PedicelDetection&)>;
/// Sees each tomato look (TrussEvalOptions::tomato_look): its scan, the
/// vision's tomatoes in that scan's frame, and the registration.
using LookObserver = std::function<void(std::uint64_t seed, const TrussScene&, const SimulatedScan& look,
                                        const std::vector<ExpectedTomato>& tomatoes, const TomatoRegistration&)>;
[[nodiscard]] TrussResult run_truss_case(TrussCase c, Scanner& scanner, int trials, std::uint64_t seed0,
                                         const TrussEvalOptions& o = {}, const TrussObserver& on_trial = {},
                                         const LookObserver& on_look = {});

// ---------------------------------------------------------------------------- Figure 5.8 B

struct StickTrial {
  std::uint64_t seed = 0;
  double iou_reflectance = 0.0;  ///< best cluster vs the stick's pure pixels
  double iou_distance_only = 0.0;
};

struct StickResult {
  std::vector<StickTrial> trials;
  Rate reflectance_correct, distance_only_correct;  ///< IoU >= min_iou
};

struct StickEvalOptions {
  StickOptions scene;
  ReflectanceClusteringParams clustering;  ///< use_reflectance is set per method
  double min_iou = 0.8;
};

using StickObserver =
    std::function<void(const StickTrial&, const StickScene&, const SimulatedScan&,
                       const ReflectanceClusteringResult& with, const ReflectanceClusteringResult& without)>;
[[nodiscard]] StickResult run_stick_case(Scanner& scanner, int trials, std::uint64_t seed0,
                                         const StickEvalOptions& o = {}, const StickObserver& on_trial = {});

// ---------------------------------------------------------------------------- wrench (5.3.2)

struct WrenchTrial {
  std::uint64_t seed = 0;
  AlignmentOutcome outcome = AlignmentOutcome::kInvalidInput;
  double true_pitch_rad = 0.0;
  double best_pitch_rad = 0.0;
  double error_rad = 0.0;       ///< |best - true|; infinite when no pitch was found
  double step_error_rad = 0.0;  ///< the same for the brightest sample alone (no refinement)
};

struct WrenchResult {
  std::vector<WrenchTrial> trials;
  double median_error_deg = 0.0, p90_error_deg = 0.0;
  double median_step_error_deg = 0.0;  ///< without the sub-step refinement
  Rate within_1deg, found;
};

struct WrenchEvalOptions {
  WrenchOptions scene;
  SurfaceReflectanceParams surface;
  AlignmentParams alignment;
  double sweep_from_deg = -16.0, sweep_to_deg = 16.0, sweep_step_deg = 2.0;
};

using WrenchObserver = std::function<void(const WrenchTrial&, const std::vector<AlignmentSample>&)>;
[[nodiscard]] WrenchResult run_wrench_case(Scanner& scanner, int trials, std::uint64_t seed0,
                                           const WrenchEvalOptions& o = {}, const WrenchObserver& on_trial = {});

}  // namespace tinyline::laser_clustering::eval
