// SPDX-License-Identifier: Apache-2.0
// Pedicel finder on hand-made scans: the move it reports, and its explicit
// outcomes.
#include <cmath>
#include <limits>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/pedicel_finder.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
using lc::PedicelOutcome;
using lc::test::Disc;
using lc::test::synth_scan;
using lc::test::SynthParams;
using ::testing::HasSubstr;

namespace tinyline::laser_clustering {
// Readable outcomes in failure messages.
inline void PrintTo(PedicelOutcome o, std::ostream* os) { *os << to_string(o); }
}  // namespace tinyline::laser_clustering

namespace {

lc::PedicelDetection detect(const lc::LineScan& scan, const lc::PedicelFinderParams& p = {},
                            const std::optional<lc::PedicelExpectation>& e = std::nullopt) {
  const auto objects = lc::cluster_line_scan(scan);
  return lc::find_pedicel(scan, objects, p, e);
}

SynthParams with_wall(unsigned seed, double wall_z = 0.40) {
  SynthParams sp;
  sp.wall_z_m = wall_z;
  sp.seed = seed;
  return sp;
}

}  // namespace

TEST(PedicelFinder, OffsetPedicelGivesTheMoveThatCentresIt) {
  // Throat at (0, 0.12); pedicel 2.5 cm to +x and 1 cm deeper.
  const auto s = synth_scan({{0.025, 0.13, 0.003, 6.0, 1}}, with_wall(1));
  const auto d = detect(s.scan);
  ASSERT_EQ(d.outcome, PedicelOutcome::kMove) << d.reason;
  // The centroid is on the rod's front surface (about 1 to 2 mm before its axis).
  EXPECT_NEAR(d.lateral_offset_m, 0.025, 0.0015);
  EXPECT_NEAR(d.depth_offset_m, 0.01 - 0.002, 0.003);
  EXPECT_NEAR(d.angle_rad, std::atan2(0.025, 0.128), 0.01);
  EXPECT_NEAR(d.width_m, 0.006, 0.0015);
  EXPECT_GT(d.confidence, 0.8);
  ASSERT_EQ(d.candidates.size(), 1u);
}

TEST(PedicelFinder, PedicelBetweenTheBladesIsCutHere) {
  const auto s = synth_scan({{0.003, 0.122, 0.003, 6.0, 1}}, with_wall(2));
  const auto d = detect(s.scan);
  EXPECT_EQ(d.outcome, PedicelOutcome::kCutHere) << d.reason;
  EXPECT_NEAR(d.lateral_offset_m, 0.003, 0.0015);
}

TEST(PedicelFinder, NearestOfTwoPedicelsWinsAndAmbiguityLowersConfidence) {
  const auto clear = synth_scan({{0.004, 0.12, 0.003, 6.0, 1}, {0.05, 0.12, 0.003, 6.0, 2}}, with_wall(3));
  const auto a = detect(clear.scan);
  ASSERT_EQ(a.outcome, PedicelOutcome::kCutHere) << a.reason;
  EXPECT_NEAR(a.position_xz_m.x(), 0.004, 0.0015);
  EXPECT_EQ(a.candidates.size(), 2u);
  // Two pedicels equally far from the throat: still an answer, low confidence.
  const auto tie = synth_scan({{-0.03, 0.12, 0.003, 6.0, 1}, {0.03, 0.12, 0.003, 6.0, 2}}, with_wall(3));
  const auto b = detect(tie.scan);
  ASSERT_EQ(b.outcome, PedicelOutcome::kMove);
  EXPECT_LT(b.confidence, 0.65);
  EXPECT_LT(b.confidence, a.confidence);
}

TEST(PedicelFinder, ExpectationFromVisionOverridesTheThroat) {
  const auto s = synth_scan({{0.01, 0.12, 0.003, 6.0, 1}, {0.05, 0.12, 0.003, 6.0, 2}}, with_wall(4));
  lc::PedicelExpectation e{{0.045, 0.12}, 0.015, {}, 0.015};
  const auto d = detect(s.scan, {}, e);
  ASSERT_EQ(d.outcome, PedicelOutcome::kMove);
  EXPECT_NEAR(d.position_xz_m.x(), 0.05, 0.0015);
}

// Table 4.3's random offset: the target 4 cm off the throat, its neighbour
// (5 cm to its left) nearer the throat. The nearest pedicel is the wrong one;
// the vision's layout of the truss, shifted onto each candidate, is not.
TEST(PedicelFinder, TrussLayoutPicksTheTargetOverANearerNeighbour) {
  const auto s = synth_scan({{-0.01, 0.12, 0.003, 6.0, 1}, {0.04, 0.12, 0.003, 6.0, 2}}, with_wall(4));
  const auto nearest = detect(s.scan);
  ASSERT_EQ(nearest.outcome, PedicelOutcome::kMove);
  EXPECT_NEAR(nearest.position_xz_m.x(), -0.01, 0.0015) << "without the layout the nearest wins";

  lc::PedicelExpectation e{{0.0, 0.12}, 0.03, {}, 0.015};
  e.neighbours.push_back({{-0.05, 0.12}, false});
  const auto d = detect(s.scan, {}, e);
  ASSERT_EQ(d.outcome, PedicelOutcome::kMove) << d.reason;
  EXPECT_NEAR(d.position_xz_m.x(), 0.04, 0.0015);
  ASSERT_EQ(d.candidates.size(), 2u);
  EXPECT_GT(d.candidates[0].layout_score, 2.0 * d.candidates[1].layout_score);

  // A neighbour that may not cross the plane explains a candidate but is
  // never missed: taking the nearer pedicel then costs only the unexplained
  // target (x 0.3), which still overturns the position prior (0.95 x 0.3
  // against 0.41), by less than when the neighbour had to be there.
  e.neighbours.front().may_be_absent = true;
  const auto m = detect(s.scan, {}, e);
  EXPECT_NEAR(m.position_xz_m.x(), 0.04, 0.0015);
  ASSERT_EQ(m.candidates.size(), 2u);
  EXPECT_LT(m.candidates[0].weight / m.candidates[1].weight, d.candidates[0].weight / d.candidates[1].weight);
  EXPECT_LT(m.confidence, d.confidence) << "the weaker layout evidence makes it less sure";

  // A neighbour with a non-finite position is invalid input.
  e.neighbours.push_back({{std::numeric_limits<double>::quiet_NaN(), 0.12}, false});
  const auto bad = detect(s.scan, {}, e);
  EXPECT_EQ(bad.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(bad.reason, HasSubstr("neighbour 1"));
}

TEST(PedicelFinder, AfterCentringThePedicelIsExpectedInTheThroatWithTheLayoutMovedAlong) {
  lc::PedicelFinderParams p;
  p.scissors.centre_x_m = 0.01;
  p.recentre_sd_m = 0.008;
  // Without a layout: the throat, with the re-centring spread.
  const auto bare = lc::expectation_after_centring(p, std::nullopt);
  EXPECT_EQ(bare.position_xz_m, Eigen::Vector2d(0.01, 0.12));
  EXPECT_DOUBLE_EQ(bare.sd_m, 0.008);
  EXPECT_TRUE(bare.neighbours.empty());
  // With one: each neighbour keeps its place relative to the expected pedicel.
  lc::PedicelExpectation before{{0.03, 0.14}, 0.03, {}, 0.012};
  before.neighbours.push_back({{-0.03, 0.15}, true});
  const auto after = lc::expectation_after_centring(p, before);
  EXPECT_EQ(after.position_xz_m, Eigen::Vector2d(0.01, 0.12));
  ASSERT_EQ(after.neighbours.size(), 1u);
  EXPECT_NEAR(after.neighbours[0].position_xz_m.x(), -0.05, 1e-12);
  EXPECT_NEAR(after.neighbours[0].position_xz_m.y(), 0.13, 1e-12);
  EXPECT_TRUE(after.neighbours[0].may_be_absent);
  EXPECT_DOUBLE_EQ(after.neighbour_sd_m, 0.012);

  // The second scan of the loop: the gripper moved onto the pedicel it chose
  // (here 2 cm short in depth, as a biased first range would leave it); the
  // finder re-centres on it, not on the neighbour 4 cm off.
  const auto s = synth_scan({{0.012, 0.142, 0.003, 6.0, 1}, {-0.03, 0.125, 0.003, 6.0, 2}}, with_wall(9));
  const auto d = detect(s.scan, p, lc::expectation_after_centring(p, std::nullopt));
  ASSERT_EQ(d.outcome, PedicelOutcome::kMove) << d.reason;
  EXPECT_NEAR(d.lateral_offset_m, 0.002, 0.0015);
  EXPECT_NEAR(d.depth_offset_m, 0.02 - 0.002, 0.003);

  p.recentre_sd_m = 0.0;
  const auto bad = detect(s.scan, p);
  EXPECT_EQ(bad.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(bad.reason, HasSubstr("recentre_sd_m must be > 0"));
}

// The loop carries the first scan's runners-up along: after the move onto
// the chosen pedicel, each stays where the move put it, with its weight
// against the chosen one's, and the next scan's layout can overturn the
// choice (the 1 cm re-centring prior alone never would).
TEST(PedicelFinder, RunnersUpCarriedIntoTheNextScanCanWinOnItsLayout) {
  lc::PedicelFinderParams p;  // throat at (0, 0.12)
  lc::PedicelExpectation before{{0.0, 0.12}, 0.03, {}, 0.015};
  before.neighbours.push_back({{-0.05, 0.12}, false});
  lc::PedicelDetection first;
  first.candidates.resize(3);
  first.candidates[0].position_xz_m = {0.02, 0.13};
  first.candidates[0].weight = 0.4;
  first.candidates[1].position_xz_m = {0.07, 0.125};
  first.candidates[1].weight = 0.2;
  first.candidates[2].position_xz_m = {-0.03, 0.12};
  first.candidates[2].weight = 0.04;
  const auto after = lc::expectation_after_centring(p, before, first);
  EXPECT_EQ(after.position_xz_m, Eigen::Vector2d(0.0, 0.12));
  EXPECT_DOUBLE_EQ(after.sd_m, p.recentre_sd_m);
  ASSERT_EQ(after.neighbours.size(), 1u);
  ASSERT_EQ(after.alternatives.size(), 2u);
  EXPECT_NEAR(after.alternatives[0].position_xz_m.x(), 0.05, 1e-12);
  EXPECT_NEAR(after.alternatives[0].position_xz_m.y(), 0.115, 1e-12);
  EXPECT_DOUBLE_EQ(after.alternatives[0].weight, 0.5);
  EXPECT_NEAR(after.alternatives[1].position_xz_m.x(), -0.05, 1e-12);
  EXPECT_DOUBLE_EQ(after.alternatives[1].weight, 0.1);
  // Nothing chosen, nothing carried.
  EXPECT_TRUE(lc::expectation_after_centring(p, before, lc::PedicelDetection{}).alternatives.empty());

  // The next scan: the chosen pedicel in the throat, the runner-up 5 cm to
  // +x, and nothing where the layout wants the chosen one's neighbour
  // (-5 cm): the runner-up explains the chosen one as its neighbour.
  const auto s = synth_scan({{0.0, 0.12, 0.003, 6.0, 1}, {0.05, 0.12, 0.003, 6.0, 2}}, with_wall(10));
  lc::PedicelExpectation e = lc::expectation_after_centring(p, before);
  const auto stay = detect(s.scan, p, e);
  ASSERT_EQ(stay.outcome, PedicelOutcome::kCutHere) << "without the runner-up: " << stay.reason;
  e.alternatives.push_back({{0.05, 0.12}, 0.5});
  const auto moved = detect(s.scan, p, e);
  ASSERT_EQ(moved.outcome, PedicelOutcome::kMove) << moved.reason;
  EXPECT_NEAR(moved.lateral_offset_m, 0.05, 0.0015);
  // A runner-up the first scan barely considered does not.
  e.alternatives.back().weight = 0.02;
  EXPECT_EQ(detect(s.scan, p, e).outcome, PedicelOutcome::kCutHere);

  e.alternatives.back().weight = 0.0;
  const auto bad = detect(s.scan, p, e);
  EXPECT_EQ(bad.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(bad.reason, HasSubstr("alternative 0"));
  e.alternatives.back() = {{std::numeric_limits<double>::quiet_NaN(), 0.12}, 0.5};
  EXPECT_EQ(detect(s.scan, p, e).outcome, PedicelOutcome::kInvalidInput);
}

// A move that centres nothing (backing off, lowering the plane to look at
// the tomatoes): every candidate is expected where the move put it.
TEST(PedicelFinder, AfterAMoveTheCandidatesAreExpectedWhereTheMovePutThem) {
  lc::PedicelFinderParams p;  // throat at (0, 0.12)
  lc::PedicelDetection seen;
  seen.candidates.resize(3);
  seen.candidates[0].position_xz_m = {0.02, 0.13};
  seen.candidates[0].weight = 0.5;
  seen.candidates[1].position_xz_m = {-0.04, 0.12};
  seen.candidates[1].weight = 0.1;
  seen.candidates[2].position_xz_m = {0.08, 0.15};
  seen.candidates[2].weight = 0.0;  // weightless: not carried (an alternative needs a weight in (0, 1])
  lc::PedicelExpectation before{{0.0, 0.12}, 0.03, {}, 0.015};
  before.neighbours.push_back({{0.06, 0.12}, false});
  const Eigen::Vector2d back(0.0, -0.08);
  const auto e = lc::expectation_after_move(p, before, seen, back);
  EXPECT_NEAR((e.position_xz_m - Eigen::Vector2d(0.02, 0.21)).norm(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(e.sd_m, p.recentre_sd_m);
  ASSERT_EQ(e.alternatives.size(), 1u);
  EXPECT_NEAR((e.alternatives[0].position_xz_m - Eigen::Vector2d(-0.04, 0.20)).norm(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(e.alternatives[0].weight, 0.2);
  ASSERT_EQ(e.neighbours.size(), 1u);  // the layout hangs on the chosen pedicel
  EXPECT_NEAR((e.neighbours[0].position_xz_m - Eigen::Vector2d(0.08, 0.21)).norm(), 0.0, 1e-12);
  // Centring is the move that takes the chosen pedicel to the throat.
  const auto c = lc::expectation_after_centring(p, before, seen);
  const auto m = lc::expectation_after_move(p, before, seen, Eigen::Vector2d(0.02, 0.01));
  EXPECT_NEAR((c.position_xz_m - m.position_xz_m).norm(), 0.0, 1e-12);
  EXPECT_NEAR((c.position_xz_m - Eigen::Vector2d(0.0, 0.12)).norm(), 0.0, 1e-12);
  ASSERT_EQ(c.alternatives.size(), m.alternatives.size());
  EXPECT_NEAR((c.alternatives[0].position_xz_m - m.alternatives[0].position_xz_m).norm(), 0.0, 1e-12);
  // Nothing chosen: what was expected moves with the gripper.
  const auto none = lc::expectation_after_move(p, before, lc::PedicelDetection{}, back);
  EXPECT_NEAR((none.position_xz_m - Eigen::Vector2d(0.0, 0.20)).norm(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(none.sd_m, 0.03);
}

// An expectation sure of itself (the truss registered on its tomatoes)
// gates: a pedicel far from it is not the one looked for, and the answer is
// "nothing to cut here", not a move to it.
TEST(PedicelFinder, AGatedExpectationDoesNotMoveToAPedicelFarFromIt) {
  const auto s = synth_scan({{0.06, 0.125, 0.003, 6.0, 1}}, with_wall(21));
  lc::PedicelExpectation e{{0.0, 0.12}, 0.012, {}, 0.015};
  const auto open = detect(s.scan, {}, e);
  ASSERT_EQ(open.outcome, PedicelOutcome::kMove) << open.reason;
  e.gate_sd = 4.0;  // 4.8 cm
  const auto gated = detect(s.scan, {}, e);
  EXPECT_EQ(gated.outcome, PedicelOutcome::kNothingToCut);
  EXPECT_THAT(gated.reason, HasSubstr("none within 0.048 m"));
  EXPECT_TRUE(gated.candidates.empty());
  // Within the gate it is a candidate as before.
  e.position_xz_m = {0.03, 0.12};
  EXPECT_EQ(detect(s.scan, {}, e).outcome, PedicelOutcome::kMove);
  // An alternative near it opens the gate there too.
  e.position_xz_m = {0.0, 0.12};
  e.alternatives.push_back({{0.055, 0.125}, 0.5});
  EXPECT_EQ(detect(s.scan, {}, e).outcome, PedicelOutcome::kMove);
  e.gate_sd = 0.0;
  const auto bad = detect(s.scan, {}, e);
  EXPECT_EQ(bad.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(bad.reason, HasSubstr("gate_sd"));
}

TEST(PedicelFinder, TomatoesAndStemsAloneAreNothingToCut) {
  // A tomato (3 cm radius) and a 2 cm stem: objects in range, none 6 mm wide.
  const auto s = synth_scan({{-0.03, 0.2, 0.03, 6.0, 1}, {0.05, 0.15, 0.01, 6.0, 2}}, with_wall(5));
  const auto d = detect(s.scan);
  EXPECT_EQ(d.outcome, PedicelOutcome::kNothingToCut) << d.reason;
  EXPECT_THAT(d.reason, HasSubstr("none pedicel-like"));
  EXPECT_EQ(d.cluster, -1);
}

TEST(PedicelFinder, NothingInRangeIsOutOfView) {
  // Only a wall at 1 m, beyond the 0.35 m working range.
  const auto far = synth_scan({}, with_wall(6, 1.0));
  const auto d = detect(far.scan);
  EXPECT_EQ(d.outcome, PedicelOutcome::kOutOfView);
  EXPECT_THAT(d.reason, HasSubstr("no return between 0.050 and 0.350 m"));
  // All pixels invalid.
  lc::LineScan dark = far.scan;
  for (auto& r : dark.range_m) r = std::numeric_limits<double>::quiet_NaN();
  const auto e = detect(dark);
  EXPECT_EQ(e.outcome, PedicelOutcome::kOutOfView);
  EXPECT_THAT(e.reason, HasSubstr("0 valid pixels of 256"));
  // Empty scan.
  const auto f = detect(lc::LineScan{});
  EXPECT_EQ(f.outcome, PedicelOutcome::kOutOfView);
  EXPECT_EQ(f.reason, "empty scan");
}

TEST(PedicelFinder, PedicelCutByTheFieldOfViewIsOutOfView) {
  const double a = 35.0 * std::numbers::pi / 180.0;
  SynthParams sp;
  sp.seed = 7;
  const auto s = synth_scan({{0.12 * std::sin(a) - 0.001, 0.12 * std::cos(a), 0.003, 6.0, 1}}, sp);
  const auto d = detect(s.scan);
  EXPECT_EQ(d.outcome, PedicelOutcome::kOutOfView) << d.reason;
  EXPECT_THAT(d.reason, HasSubstr("cut by the edge of the field of view"));
}

TEST(PedicelFinder, BadInputIsInvalidInputWithAReason) {
  const auto s = synth_scan({{0.0, 0.12, 0.003, 6.0, 1}}, with_wall(8));
  lc::PedicelFinderParams p;
  p.diameter_m = -0.006;
  auto d = detect(s.scan, p);
  EXPECT_EQ(d.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(d.reason, HasSubstr("diameter_m must be > 0"));
  p = {};
  p.max_range_m = 0.01;
  EXPECT_THAT(detect(s.scan, p).reason, HasSubstr("min_range_m < max_range_m"));
  // Clusters of another scan.
  const auto objects = lc::cluster_line_scan(s.scan);
  lc::LineScan shorter = s.scan;
  shorter.angle_rad.resize(100);
  shorter.range_m.resize(100);
  d = lc::find_pedicel(shorter, objects, {});
  EXPECT_EQ(d.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(d.reason, HasSubstr("256 labels for a scan of 100 pixels"));
  // A failed clustering passes its reason on.
  lc::LineScan broken = s.scan;
  broken.range_m.pop_back();
  d = detect(broken);
  EXPECT_EQ(d.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(d.reason, HasSubstr("clustering failed"));
  // A NaN expectation.
  d = detect(s.scan, {}, lc::PedicelExpectation{{std::numeric_limits<double>::quiet_NaN(), 0.1}, 0.01, {}, 0.015});
  EXPECT_EQ(d.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_STREQ(lc::to_string(d.outcome), "invalid_input");
}

TEST(PedicelFinder, TheRangeBiasMovesEveryCentreBackAlongItsBearing) {
  const auto s = synth_scan({{0.03, 0.15, 0.003, 6.0, 1}}, with_wall(3));
  const auto plain = detect(s.scan);
  lc::PedicelFinderParams p;
  p.range_bias_m = 0.01;
  const auto corrected = detect(s.scan, p);
  ASSERT_EQ(plain.outcome, PedicelOutcome::kMove) << plain.reason;
  ASSERT_EQ(corrected.outcome, PedicelOutcome::kMove) << corrected.reason;
  EXPECT_NEAR(plain.position_xz_m.norm() - corrected.position_xz_m.norm(), 0.01, 1e-9);
  EXPECT_NEAR(std::atan2(corrected.position_xz_m.x(), corrected.position_xz_m.y()),
              std::atan2(plain.position_xz_m.x(), plain.position_xz_m.y()), 1e-9);
  EXPECT_NEAR(plain.depth_offset_m - corrected.depth_offset_m, 0.01 * 0.15 / std::hypot(0.03, 0.15), 0.001);
}
