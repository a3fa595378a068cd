// SPDX-License-Identifier: Apache-2.0
// The harvest of one detection, pick by pick (thesis 4.4-4.5, Table 4.2):
// what the gripper does after each laser verification and each closing of
// the scissors. A pick starts at the picking pose (attempt 1):
//
//   verification  cut here        -> close the blades there
//                 move            -> attempt 1: move, and re-scan there
//                                    (the thesis's second attempt);
//                                    the last attempt: move and close
//                 nothing found,  -> while attempts remain: scan again from
//                 out of view        the pose turned about the pedicel
//                                    (another side may show what this one
//                                    hid), else left for a human
//   blades        cut the target  -> picked (at this attempt)
//                 jammed          -> a cut failure
//                 cut another's   -> that fruit fell; this one is not picked
//                 closed on nothing -> as nothing found
//
// The gripper's report comes back as plain values (BladeResult) so that this
// core depends on no simulator.
#pragma once

#include <string>

#include <Eigen/Geometry>

#include <tinyline/common/validation.hpp>

#include "tomato_reasoning/pick_pose.hpp"

namespace tinyline::tomato_reasoning {

struct HarvestParams {
  /// Laser scans per pick: 2 = the picking pose, then one re-scan after the
  /// finder's move or an empty closing (Table 4.2's SP(1) and SP(2)).
  int max_attempts = 2;
  /// A later attempt after nothing found or an empty closing comes from the
  /// pose turned about the pedicel by this much, alternating sides [deg].
  double retry_roll_deg = 30.0;
};
[[nodiscard]] common::Validation validate(const HarvestParams& p);

/// What closing the blades did, as the gripper reports it.
enum class BladeResult { kCutTarget, kCutOtherPedicel, kClosedOnNothing, kJammed };
[[nodiscard]] const char* to_string(BladeResult r);

/// How a pick ended (Table 4.2: SP, CF, and HS for the rest).
enum class PickOutcome { kPicked, kCutFailure, kCutOther, kLeftForHuman };
[[nodiscard]] const char* to_string(PickOutcome o);

struct GripperStep {
  enum class Action { kCut, kRescan, kDone };
  Action action = Action::kDone;
  /// kCut: close the blades with the laser here; kRescan: scan from here.
  Eigen::Isometry3d T_ref_laser = Eigen::Isometry3d::Identity();
  PickOutcome outcome = PickOutcome::kLeftForHuman;  ///< kDone
};

/// One pick's attempts. Start with the picking pose; feed it the
/// verification of each scan and the gripper's report of each closing.
class PickAttempts {
 public:
  PickAttempts(const PickPose& pose, const HarvestParams& params);

  [[nodiscard]] int attempt() const { return attempt_; }  ///< 1-based
  /// Where the laser scans for the current attempt (the picking pose, or
  /// where the last move or empty closing left it).
  [[nodiscard]] const PickPose& pose() const { return pose_; }
  /// Every step so far in words ("1: move 12 mm; 2: cut here -> cut target").
  [[nodiscard]] const std::string& detail() const { return detail_; }
  [[nodiscard]] bool done() const { return done_; }

  [[nodiscard]] GripperStep after_verification(const Verification& v);
  [[nodiscard]] GripperStep after_cut(BladeResult r);

 private:
  GripperStep finish(PickOutcome o);
  GripperStep rescan();
  GripperStep retry_elsewhere();
  void note(const std::string& s);
  PickPose pose_;
  HarvestParams params_;
  int attempt_ = 1;
  bool done_ = false;
  std::string detail_;
};

}  // namespace tinyline::tomato_reasoning
