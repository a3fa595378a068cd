// SPDX-License-Identifier: Apache-2.0
// Scoring of the tomato pipeline against a simulated truss's truth, as
// docs/tomato_reasoning.md reports it (thesis 4.5, Table 4.2):
//   detection   a true tomato counts as detected when a sphere's centre lies
//               within 1 cm of its centre (one sphere per tomato);
//   errors      centre and radius error of the detected ones;
//   pedicel     angle between the expected pedicel direction and the truth,
//               and whether the truth lies in the distribution's most
//               probable 50% (calibration: about half the time);
//   graph       contact edges against the truth's fruit-fruit contacts.
#pragma once

#include <string>
#include <vector>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::eval {

struct ScoreParams {
  double match_distance_m = 0.01;  ///< the thesis-style detection criterion
  double hpd_mass = 0.5;           ///< calibration region
  /// A tomato counts as "visible" when at least this share of the disc it
  /// would show unoccluded is seen by the camera.
  double visible_share = 0.25;
};

struct TomatoScore {
  int truth = -1;
  int detection = -1;          ///< index into PipelineResult::tomatoes, -1 if missed
  double visible_share = 0.0;  ///< seen pixels / pixels of its unoccluded disc
  double centre_error_m = NAN;
  double radius_error_m = NAN;               ///< estimate - truth
  double centre_toward_camera_m = NAN;       ///< centre error along the ray, positive towards the camera
  double depth_noise_m = NAN;                ///< the depth noise measured around the sphere (0: not measured)
  double uncorrected_radius_error_m = NAN;   ///< signed, before the noise bias was removed
  double uncorrected_toward_camera_m = NAN;  ///< ... and the centre's along the ray
  int edges_true = 0;
  int edges_estimated = -1;
  double pedicel_error_deg = NAN;        ///< expected direction vs the true pedicel
  double prior_pedicel_error_deg = NAN;  ///< ... the force model's alone (before the seen pedicel)
  bool pedicel_seen = false;             ///< the camera saw the pedicel or calyx (a sighting)
  int seen_points = 0;
  double seen_error_deg = NAN;          ///< the sighting's own direction vs the true pedicel
  double cut_point_axis_mm = NAN;       ///< planned cut point's distance from the true pedicel's path [mm]
  double gravity_only_error_deg = NAN;  ///< straight up (no reasoning) vs the true pedicel
  double force_dir_error_deg = NAN;     ///< expected direction vs the true pedicel *force*
  bool truth_in_hpd = false;
  double spread50_deg = NAN;
  double cut_coverage = NAN;      ///< predicted probability inside the planned cut's cover
  bool cut_covers_truth = false;  ///< the true pedicel lies inside the planned cut's cover
  int pick_rank = -1;
};

struct TrussScore {
  char complexity = 'B';
  std::uint64_t seed = 0;
  bool ok = false;
  std::string stage, reason;
  int truth = 0;
  int detected = 0;
  int visible = 0;  ///< tomatoes with visible_share >= the threshold
  int visible_detected = 0;
  int detections = 0;
  int unmatched = 0;                             ///< spheres not within match_distance of any tomato
  int on_distractor = 0;                         ///< ... of which near a fruit of the second branch
  int edges_tp = 0, edges_fp = 0, edges_fn = 0;  ///< among detected tomatoes
  bool first_pick_real = false;                  ///< the first pick is a detected true tomato
  StageTimes times;
  std::vector<TomatoScore> tomatoes;
};

[[nodiscard]] TrussScore score_truss(const Scenario& s, const PipelineResult& r, const ScoreParams& p = {});

/// The pick order as indices of the true tomatoes: each pick's nearest true
/// centre within p.match_distance_m, -1 when none is that near.
[[nodiscard]] std::vector<int> pick_order_in_truth(const Scenario& s, const PipelineResult& r,
                                                   const ScoreParams& p = {});

/// A reason's words with every number as N and nothing from the first '('
/// on ("the laser sees 2 objects (...)" -> "the laser sees N objects"), so
/// that reasons differing only in their figures count together.
[[nodiscard]] std::string without_figures(const std::string& reason);

struct Summary {
  int trusses = 0, truth = 0, detected = 0, visible = 0, visible_detected = 0, detections = 0, unmatched = 0;
  double centre_median_mm = NAN, centre_p95_mm = NAN;
  double radius_median_mm = NAN, radius_p95_mm = NAN;  ///< of |error|
  double pedicel_median_deg = NAN, pedicel_p95_deg = NAN;
  double prior_pedicel_median_deg = NAN;  ///< the force model alone
  double radius_bias_mm = NAN;            ///< median of the signed radius error (estimate - truth)
  double centre_toward_camera_mm = NAN;   ///< median centre error along the ray, positive towards the camera
  int seen = 0;                           ///< detected tomatoes whose pedicel was seen
  double seen_prior_median_deg = NAN, seen_posterior_median_deg = NAN;  ///< over the seen ones
  double gravity_only_median_deg = NAN, gravity_only_p95_deg = NAN;
  double hpd_hit_rate = NAN;
  double cut_cover_rate = NAN;     ///< how often the planned cut covers the true pedicel
  double mean_cut_coverage = NAN;  ///< ... and how often it expected to
  double edge_precision = NAN, edge_recall = NAN;
  double total_ms_median = NAN, total_ms_p95 = NAN;
};

[[nodiscard]] Summary summarize(const std::vector<TrussScore>& scores);

/// Percentile (0-100) by linear interpolation; NaN for an empty set.
[[nodiscard]] double percentile(std::vector<double> v, double pct);

/// One CSV line per true tomato (header first), for the plotting scripts.
[[nodiscard]] std::string csv_header();
[[nodiscard]] std::string csv_rows(const TrussScore& s);
/// The summary as a JSON object.
[[nodiscard]] std::string to_json(const Summary& s);

}  // namespace tinyline::tomato_reasoning::eval
