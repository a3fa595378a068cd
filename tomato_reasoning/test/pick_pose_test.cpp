// SPDX-License-Identifier: Apache-2.0
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "tomato_reasoning/pick_pose.hpp"

namespace tinyline::tomato_reasoning {
namespace {

TEST(PickingPose, PutsTheThroatOnTheCutWithTheLineAcrossThePedicel) {
  PickPoseParams p;
  p.approach_from = Eigen::Vector3d(0, 0, 0);
  const Eigen::Vector3d cut(0.05, -0.02, 0.45), pedicel = Eigen::Vector3d(0.2, -1.0, 0.1).normalized();
  const PickPose pose = picking_pose(cut, pedicel, p);
  ASSERT_TRUE(pose.ok()) << pose.reason;
  EXPECT_LT((pose.T_ref_laser * Eigen::Vector3d(0, 0, p.throat_z_m) - cut).norm(), 1e-12);
  const Eigen::Matrix3d R = pose.T_ref_laser.linear();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_NEAR(R.col(1).dot(pedicel), 1.0, 1e-12);       // the laser plane (x-z) is square to the pedicel
  EXPECT_GT(R.col(2).dot(cut - p.approach_from), 0.0);  // looking from the robot's side
}

// A fruit between the laser and the pedicel hides it: the pose turns about
// the pedicel, as little as clears the view; nothing in the way, no turn.
TEST(PickingPose, TurnsAboutThePedicelToSeePastAFruitInFront) {
  PickPoseParams p;
  const Eigen::Vector3d cut(0.0, -0.038, 0.5), up(0, -1, 0);
  Sphere front;  // straight on the line from the camera's side, cut by the scan plane
  front.centre = Eigen::Vector3d(0.0, -0.03, 0.43);
  front.radius_m = 0.03;
  const PickPose straight = picking_pose(cut, up, p);
  const PickPose turned = picking_pose(cut, up, std::vector<Sphere>{front}, p);
  ASSERT_TRUE(turned.ok());
  EXPECT_LT((turned.T_ref_laser * Eigen::Vector3d(0, 0, p.throat_z_m) - cut).norm(),
            1e-12);                                                     // the throat stays on the cut
  EXPECT_NEAR(turned.T_ref_laser.linear().col(1).dot(up), 1.0, 1e-12);  // still square to the pedicel
  const double turn =
      std::acos(std::clamp(turned.T_ref_laser.linear().col(2).dot(straight.T_ref_laser.linear().col(2)), -1.0, 1.0));
  EXPECT_GT(turn, 0.2);
  EXPECT_LE(turn, p.max_turn_deg * M_PI / 180.0 + 1e-9);
  // The turned laser's ray to the throat passes the fruit.
  const Eigen::Vector3d o = turned.T_ref_laser.translation(), d = (cut - o).normalized();
  const Eigen::Vector3d w = front.centre - o;
  EXPECT_GT((w - w.dot(d) * d).norm(), front.radius_m);
  Sphere aside = front;  // well off the line of sight
  aside.centre.x() = 0.15;
  const PickPose clear = picking_pose(cut, up, std::vector<Sphere>{aside}, p);
  EXPECT_LT((clear.T_ref_laser.matrix() - straight.T_ref_laser.matrix()).norm(), 1e-12);
  p.max_turn_deg = 0;  // turning off: the straight approach whatever is in front
  EXPECT_LT((picking_pose(cut, up, std::vector<Sphere>{front}, p).T_ref_laser.matrix() - straight.T_ref_laser.matrix())
                .norm(),
            1e-12);
}

TEST(PickingPose, BadInputGivesNoPoseAndTheReason) {
  const double nan = std::nan("");
  EXPECT_FALSE(picking_pose(Eigen::Vector3d(nan, 0, 0.4), Eigen::Vector3d::UnitY()).ok());
  EXPECT_FALSE(picking_pose(Eigen::Vector3d(0, 0, 0.4), Eigen::Vector3d::Zero()).ok());
  // Approaching along the pedicel still gives a proper frame.
  const PickPose along = picking_pose(Eigen::Vector3d(0, 0, 0.4), Eigen::Vector3d::UnitZ());
  ASSERT_TRUE(along.ok());
  EXPECT_NEAR(along.T_ref_laser.linear().determinant(), 1.0, 1e-12);
  PipelineResult empty;
  const PickPose none = picking_pose(empty, 0);
  EXPECT_FALSE(none.ok());
  EXPECT_NE(none.reason.find("of 0"), std::string::npos);
}

// A fruit beyond the cut on the straight approach would be in the blades'
// box: the best cut rolls about the pedicel until the box clears it by the
// margin; a fruit hugging the pedicel leaves no cut that fits, and says so.
TEST(CutCandidates, RollTheBladesOffANeighbourOrSayNoneFits) {
  PickPoseParams p;
  p.max_turn_deg = 90;
  Sphere target;
  target.centre = Eigen::Vector3d(0, 0, 0.5);
  target.radius_m = 0.03;
  const Eigen::Vector3d up(0, -1, 0);
  Sphere beyond;  // level with the cut point, 3 cm further along the straight approach
  beyond.centre = Eigen::Vector3d(0, -0.038, 0.53);
  beyond.radius_m = 0.015;
  const std::vector<CutCandidate> cuts = cut_candidates(target, up, {beyond}, p);
  ASSERT_FALSE(cuts.empty());
  const PickPose straight = picking_pose(target.centre + (target.radius_m + 0.008) * up, up, p);
  EXPECT_LT(blade_clearance(straight.T_ref_laser, beyond, p), 0.0);  // the straight approach would jam
  ASSERT_TRUE(cuts.front().fits(p));
  EXPECT_GE(blade_clearance(cuts.front().pose.T_ref_laser, beyond, p), p.blades.margin_m);
  EXPECT_GE(blade_clearance(cuts.front().pose.T_ref_laser, target, p), 0.0);
  EXPECT_NE(cuts.front().roll_rad, 0.0);
  // The throat stays on the pedicel, the laser line across it.
  const Eigen::Vector3d throat = cuts.front().pose.T_ref_laser * Eigen::Vector3d(0, 0, p.throat_z_m);
  EXPECT_LT((throat - target.centre).cross(up).norm(), 1e-12);
  EXPECT_NEAR(cuts.front().pose.T_ref_laser.linear().col(1).dot(up), 1.0, 1e-12);
  Sphere hugging;  // beside the pedicel, closer than the blades' half opening
  hugging.centre = Eigen::Vector3d(0.02, -0.045, 0.5);
  hugging.radius_m = 0.012;
  const std::vector<CutCandidate> none = cut_candidates(target, up, {hugging}, p);
  ASSERT_FALSE(none.empty());
  EXPECT_FALSE(none.front().fits(p));
}

// The laser put the throat where a neighbour's sphere reaches into the
// blades: the nearby cuts on the same pedicel (moved along it, rolled about
// it) that clear it come smallest change first, the throat still on the
// pedicel's line; none of them cuts into the target's own fruit.
TEST(NearbyCuts, DodgeANeighbourInTheBladesOnTheSamePedicel) {
  PickPoseParams p;
  Sphere own;
  own.centre = Eigen::Vector3d(0, 0, 0.5);
  own.radius_m = 0.03;
  const Eigen::Vector3d up(0, -1, 0);
  const PickPose at = picking_pose(own.centre + (own.radius_m + 0.008) * up, up, p);
  Sphere beyond;  // level with the cut, 3 cm further along the straight approach
  beyond.centre = Eigen::Vector3d(0, -0.038, 0.53);
  beyond.radius_m = 0.015;
  ASSERT_LT(blade_clearance(at.T_ref_laser, beyond, p), p.blades.margin_m);
  CutProbeParams probe;
  probe.shifts_m = {0.0, 0.004, -0.003};
  probe.rolls_deg = {0.0, 60.0, -60.0, 90.0, -90.0};
  const std::vector<PickPose> near = nearby_cuts(at, own, {beyond}, p, probe);
  ASSERT_FALSE(near.empty());
  for (const PickPose& n : near) {
    EXPECT_GE(blade_clearance(n.T_ref_laser, beyond, p), p.blades.margin_m);
    EXPECT_GE(blade_clearance(n.T_ref_laser, own, p), 0.001);
    const Eigen::Vector3d throat = n.T_ref_laser * Eigen::Vector3d(0, 0, p.throat_z_m);
    EXPECT_LT((throat - own.centre).cross(up).norm(), 1e-12);  // on the pedicel's line
    EXPECT_NEAR(n.T_ref_laser.linear().col(1).dot(up), 1.0, 1e-12);
  }
  // The smallest change first: a roll at the same point, not a move along the pedicel as well.
  EXPECT_LT((near.front().cut_point - at.cut_point).norm(), 1e-12);
  // Nothing in the way: every change is offered but `at` itself.
  EXPECT_EQ(nearby_cuts(at, own, {}, p, probe).size(), probe.shifts_m.size() * probe.rolls_deg.size() - 1);
  EXPECT_TRUE(nearby_cuts(PickPose{}, own, {}, p).empty());
}

TEST(Verify, MovesTheThroatOntoThePedicelTheFinderSaw) {
  PickPoseParams p;
  const PickPose pose = picking_pose(Eigen::Vector3d(0.0, 0.0, 0.5), Eigen::Vector3d::UnitY(), p);
  ASSERT_TRUE(pose.ok());
  FinderAnswer a;
  a.outcome = FinderAnswer::Outcome::kMove;
  a.lateral_offset_m = 0.012;
  a.depth_offset_m = -0.004;
  a.confidence = 0.8;
  const Verification v = verify(pose, a, p);
  ASSERT_TRUE(v.will_cut());
  EXPECT_EQ(v.outcome, Verification::Outcome::kMove);
  // The pedicel the finder saw, in the reference frame, is where the blades now meet.
  const Eigen::Vector3d seen = pose.T_ref_laser * Eigen::Vector3d(0.012, 0, p.throat_z_m - 0.004);
  EXPECT_LT((v.cut_point - seen).norm(), 1e-12);
  EXPECT_NEAR(v.move.norm(), std::hypot(0.012, 0.004), 1e-12);
  EXPECT_STREQ(to_string(v.outcome), "move");
}

TEST(Verify, NothingFoundOutOfViewAndBadAnswersDoNotCut) {
  const PickPose pose = picking_pose(Eigen::Vector3d(0.0, 0.0, 0.5), Eigen::Vector3d::UnitY());
  FinderAnswer a;
  a.outcome = FinderAnswer::Outcome::kNothingToCut;
  EXPECT_EQ(verify(pose, a).outcome, Verification::Outcome::kNothingFound);
  a.outcome = FinderAnswer::Outcome::kOutOfView;
  EXPECT_EQ(verify(pose, a).outcome, Verification::Outcome::kOutOfView);
  a.outcome = FinderAnswer::Outcome::kMove;
  a.lateral_offset_m = std::nan("");
  const Verification v = verify(pose, a);
  EXPECT_FALSE(v.will_cut());
  EXPECT_NE(v.reason.find("non-finite"), std::string::npos);
  EXPECT_FALSE(verify(PickPose{}, FinderAnswer{}).will_cut());
  // A pedicel far beyond what the vision can be off by is someone else's.
  a.lateral_offset_m = 0.18;
  a.depth_offset_m = 0.0;
  const Verification far = verify(pose, a);
  EXPECT_EQ(far.outcome, Verification::Outcome::kNothingFound);
  EXPECT_NE(far.reason.find("max_move_m"), std::string::npos);
}

}  // namespace
}  // namespace tinyline::tomato_reasoning
