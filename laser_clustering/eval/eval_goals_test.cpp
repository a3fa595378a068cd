// SPDX-License-Identifier: Apache-2.0
// The evaluation of docs/laser_clustering.md as a test: 200 seeded trials per
// case on the simulated sensor (the same seeds and scanners as
// laser_clustering_eval), failing when a goal of docs/laser_clustering.md is missed or a
// documented figure regresses. Seconds, not minutes: the sensor model is fast.
#include <vector>

#include <gtest/gtest.h>

#include "harness.hpp"
#include "scanner.hpp"

namespace ev = tinyline::laser_clustering::eval;
namespace sim = tinyline::sim;

namespace {

constexpr int kTrials = 200;
constexpr std::uint64_t kSeed = 1;

// The evaluation's headline schedule: one a real sensor can run (the wire
// sets pulses in tens).
ev::SimScannerOptions options(const char* config, std::vector<int> pulses = {10, 20, 50, 120, 300}) {
  ev::SimScannerOptions o;
  o.sensor_config = config;
  o.raw_pulses = std::move(pulses);
  o.calibration_max_m = 0.6;
  o.calibration_step_m = 0.01;
  o.calibration_sets = 3;
  return o;
}

ev::Scanner& gripper() {
  static auto s = ev::make_sim_scanner(options("tiny_tof_3p6mm.yaml"));
  return *s;
}
ev::Scanner& tools() {
  static auto s = ev::make_sim_scanner(options("tiny_tof_8mm.yaml"));
  return *s;
}

}  // namespace

TEST(EvalGoals, RecognitionErrorCaseAlignsAtLeast85Percent) {
  const auto r = ev::run_truss_case(ev::TrussCase::kRecognitionError, gripper(), kTrials, kSeed);
  EXPECT_GE(r.aligned.p, 0.85) << "goal";
  EXPECT_GE(r.aligned.k, 195) << "documented: 200/200";
}

TEST(EvalGoals, RandomOffsetCaseAlignsAtLeast97PercentAndGoesWrongAtMostOnePercent) {
  // With the tomato look (register the vision's tomatoes on a scan through
  // them, then decide): the goal.
  const auto r = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed);
  EXPECT_GE(r.aligned.p, 0.97) << "goal; documented: 200/200";
  EXPECT_LE(r.wrong.p, 0.01) << "goal; documented: 0/200";
}

TEST(EvalGoals, TheTomatoLookBeatsThePedicelPlaneAlone) {
  ev::TrussEvalOptions no_look;
  no_look.tomato_look = false;
  const auto before = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed, no_look);
  const auto after = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed);
  EXPECT_GE(before.aligned.k, 190) << "documented: 193/200";
  EXPECT_GE(after.aligned.k, before.aligned.k + 4) << "documented: 200 vs 193";
  EXPECT_LE(after.wrong.k, before.wrong.k - 4) << "documented: 0 vs 7";
  int registered = 0;
  for (const auto& t : after.trials) registered += t.registered;
  EXPECT_GE(registered, 150) << "most looks register the truss (documented: 176/200)";
}

// The finder's own steps, each against the one before it, with the pedicel
// plane alone (no tomato look): the befores of the figures in the docs.
namespace {
ev::TrussEvalOptions pedicel_plane_only() {
  ev::TrussEvalOptions o;
  o.tomato_look = false;
  return o;
}
}  // namespace

TEST(EvalGoals, TrussLayoutBeatsTheNearestPedicelOnTheSameTrials) {
  ev::TrussEvalOptions nearest = pedicel_plane_only();
  nearest.use_layout = false;
  const auto before = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed, nearest);
  const auto after = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed, pedicel_plane_only());
  EXPECT_GE(before.aligned.k, 170) << "documented: 176/200";
  EXPECT_GE(after.aligned.k, before.aligned.k + 8) << "documented: 193 vs 176";
  EXPECT_LT(after.wrong.k, before.wrong.k);
  EXPECT_GE(after.aligned_unambiguous.p, 0.95) << "documented: 175/179";
}

TEST(EvalGoals, ClosedLoopBeatsTheFirstScanAlone) {
  // Move, scan again, re-centre (4.5): the second scan, from nearer the
  // pedicel, corrects the first one's range bias at 10-20 cm.
  ev::TrussEvalOptions first = pedicel_plane_only();
  first.rescans = 0;
  for (const auto c : {ev::TrussCase::kRandomOffset, ev::TrussCase::kRecognitionError}) {
    const auto before = ev::run_truss_case(c, gripper(), kTrials, kSeed, first);
    const auto after = ev::run_truss_case(c, gripper(), kTrials, kSeed, pedicel_plane_only());
    EXPECT_LT(after.wrong.k, before.wrong.k) << "documented: 7 vs 14 and 0 vs 14";
    EXPECT_GT(after.aligned.k, before.aligned.k);
  }
}

TEST(EvalGoals, CarryingTheRunnersUpIntoTheReScansBeatsReCentringOnTheFirstChoice) {
  // A re-scan from where the first move put the gripper may see the pedicel
  // that tells the first scan's hypotheses apart; carried along with their
  // weights, a runner-up can then win (and the next re-scan re-centres).
  ev::TrussEvalOptions chosen_only = pedicel_plane_only();
  chosen_only.carry_runners_up = false;
  const auto before = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed, chosen_only);
  const auto after = ev::run_truss_case(ev::TrussCase::kRandomOffset, gripper(), kTrials, kSeed, pedicel_plane_only());
  EXPECT_GT(after.aligned.k, before.aligned.k) << "documented: 193 vs 189";
  EXPECT_LT(after.wrong.k, before.wrong.k) << "documented: 7 vs 11";
  const auto r = ev::run_truss_case(ev::TrussCase::kRecognitionError, gripper(), kTrials, kSeed, pedicel_plane_only());
  EXPECT_EQ(r.wrong.k, 0) << "documented: 0/200 either way";
}

TEST(EvalGoals, BrushedStickSeparatesByReflectanceNotByDistanceAlone) {
  ev::StickEvalOptions o;
  o.scene.stick_material = "metal_pan";
  o.scene.front_gap_m = 0.004;
  const auto r = ev::run_stick_case(tools(), kTrials, kSeed, o);
  EXPECT_GE(r.reflectance_correct.p, 0.95) << "goal";
  EXPECT_LE(r.distance_only_correct.p, 0.80) << "distance alone should fail often";
}

TEST(EvalGoals, WrenchMedianPitchErrorUnderOneDegree) {
  const auto r = ev::run_wrench_case(tools(), kTrials, kSeed);
  EXPECT_LE(r.median_error_deg, 1.0) << "goal";
  // The polished wrench's peak saturates at 20-30 cm even at 10 pulses;
  // counting saturated pixels as lower bounds keeps the median within the
  // goal (docs: 0.27 deg; 1.74 deg without the bounds).
  EXPECT_LE(r.median_error_deg, 0.45) << "documented: 0.27 deg";
  EXPECT_LT(r.median_error_deg, r.median_step_error_deg) << "the refinement must beat the raw 2 degree steps";
  EXPECT_GE(r.within_1deg.k, 120) << "documented: 130/200";
}

// The simulator's finer schedule (3/8/25/80/250 pulses, not commandable on
// the wire) saturates nothing: the sweep's peak is whole (docs: 0.10 deg).
TEST(EvalGoals, WrenchOnTheSimulatorsFinerScheduleMedianUnderTwoTenthsOfADegree) {
  auto scanner = ev::make_sim_scanner(options("tiny_tof_8mm.yaml", {3, 8, 25, 80, 250}));
  const auto r = ev::run_wrench_case(*scanner, kTrials, kSeed);
  EXPECT_LE(r.median_error_deg, 0.2) << "documented: 0.10 deg";
  EXPECT_GE(r.within_1deg.k, 185) << "documented: 194/200";
}
