// SPDX-License-Identifier: Apache-2.0
#include <cmath>

#include <gtest/gtest.h>

#include "tomato_reasoning/harvest.hpp"

using namespace tinyline::tomato_reasoning;
using Action = GripperStep::Action;

namespace {

PickPose pose_at(double x) {
  PickPose p;
  p.tomato = 2;
  p.T_ref_laser.translation() = Eigen::Vector3d(x, 0, 0);
  p.cut_point = Eigen::Vector3d(x, 0, 0.12);
  return p;
}

Verification said(Verification::Outcome o, double move_x = 0.0) {
  Verification v;
  v.outcome = o;
  v.move = Eigen::Vector3d(move_x, 0, 0);
  v.T_ref_laser_final = pose_at(0.0).T_ref_laser;
  v.T_ref_laser_final.translation().x() += move_x;
  v.cut_point = Eigen::Vector3d(move_x, 0, 0.12);
  return v;
}

}  // namespace

TEST(Harvest, CutHereThenTheTargetIsAFirstAttemptPick) {
  PickAttempts p(pose_at(0), HarvestParams{});
  const GripperStep s = p.after_verification(said(Verification::Outcome::kCutHere));
  EXPECT_EQ(s.action, Action::kCut);
  EXPECT_EQ(s.T_ref_laser.translation().x(), 0.0);
  const GripperStep d = p.after_cut(BladeResult::kCutTarget);
  EXPECT_EQ(d.action, Action::kDone);
  EXPECT_EQ(d.outcome, PickOutcome::kPicked);
  EXPECT_EQ(p.attempt(), 1);
  EXPECT_EQ(p.detail(), "1: cut_here -> cut_target");
}

TEST(Harvest, AMoveIsFollowedByARescanThereAndTheLastAttemptCutsAfterItsMove) {
  PickAttempts p(pose_at(0), HarvestParams{});
  const GripperStep r = p.after_verification(said(Verification::Outcome::kMove, 0.012));
  EXPECT_EQ(r.action, Action::kRescan);
  EXPECT_DOUBLE_EQ(r.T_ref_laser.translation().x(), 0.012);
  EXPECT_EQ(p.attempt(), 2);
  EXPECT_DOUBLE_EQ(p.pose().T_ref_laser.translation().x(), 0.012);
  Verification again = said(Verification::Outcome::kMove, 0.004);
  again.T_ref_laser_final.translation().x() = 0.016;
  const GripperStep c = p.after_verification(again);
  EXPECT_EQ(c.action, Action::kCut);  // no third scan
  EXPECT_DOUBLE_EQ(c.T_ref_laser.translation().x(), 0.016);
  EXPECT_EQ(p.after_cut(BladeResult::kCutTarget).outcome, PickOutcome::kPicked);
  EXPECT_EQ(p.attempt(), 2);
  EXPECT_EQ(p.detail(), "1: move by 12 mm; 2: move by 4 mm -> cut_target");
}

// Nothing found: the second attempt scans from the pose turned about the
// pedicel (the throat where it was); nothing again: left for a human.
TEST(Harvest, NothingFoundIsRetriedFromAnotherSideThenLeftForAHuman) {
  for (auto o :
       {Verification::Outcome::kNothingFound, Verification::Outcome::kOutOfView, Verification::Outcome::kFailed}) {
    PickPose start = pose_at(0);
    start.pedicel_axis = Eigen::Vector3d::UnitY();
    PickAttempts p(start, HarvestParams{});
    const GripperStep r = p.after_verification(said(o));
    EXPECT_EQ(r.action, Action::kRescan);
    EXPECT_EQ(p.attempt(), 2);
    EXPECT_NEAR(r.T_ref_laser.linear().col(2).dot(Eigen::Vector3d::UnitZ()), std::cos(30.0 * M_PI / 180.0), 1e-12);
    EXPECT_LT((r.T_ref_laser * Eigen::Vector3d(0, 0, 0.12) - start.cut_point).norm(), 1e-12);
    const GripperStep s = p.after_verification(said(o));
    EXPECT_EQ(s.action, Action::kDone);
    EXPECT_EQ(s.outcome, PickOutcome::kLeftForHuman);
    EXPECT_TRUE(p.done());
  }
}

TEST(Harvest, EmptyBladesRescanOnceThenGiveUp) {
  PickAttempts p(pose_at(0), HarvestParams{});
  (void)p.after_verification(said(Verification::Outcome::kCutHere));
  const GripperStep r = p.after_cut(BladeResult::kClosedOnNothing);
  EXPECT_EQ(r.action, Action::kRescan);
  EXPECT_EQ(r.T_ref_laser.translation().x(), 0.0);  // from where the blades closed
  (void)p.after_verification(said(Verification::Outcome::kCutHere));
  const GripperStep d = p.after_cut(BladeResult::kClosedOnNothing);
  EXPECT_EQ(d.action, Action::kDone);
  EXPECT_EQ(d.outcome, PickOutcome::kLeftForHuman);
}

TEST(Harvest, JamsAndOtherPedicelsEndThePick) {
  PickAttempts a(pose_at(0), HarvestParams{});
  (void)a.after_verification(said(Verification::Outcome::kCutHere));
  EXPECT_EQ(a.after_cut(BladeResult::kJammed).outcome, PickOutcome::kCutFailure);
  PickAttempts b(pose_at(0), HarvestParams{});
  (void)b.after_verification(said(Verification::Outcome::kCutHere));
  EXPECT_EQ(b.after_cut(BladeResult::kCutOtherPedicel).outcome, PickOutcome::kCutOther);
}

TEST(Harvest, OneAttemptCutsAtTheFirstMove) {
  HarvestParams one;
  one.max_attempts = 1;
  PickAttempts p(pose_at(0), one);
  EXPECT_EQ(p.after_verification(said(Verification::Outcome::kMove, 0.01)).action, Action::kCut);
  EXPECT_EQ(p.after_cut(BladeResult::kClosedOnNothing).outcome, PickOutcome::kLeftForHuman);
  EXPECT_FALSE(validate(HarvestParams{0}).valid);
  EXPECT_TRUE(validate(HarvestParams{}).valid);
}
