// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/harvest.hpp"

#include <cmath>

namespace tinyline::tomato_reasoning {

common::Validation validate(const HarvestParams& p) {
  if (p.max_attempts < 1 || p.max_attempts > 5)
    return common::Validation::invalid("max_attempts must be 1..5, got " + std::to_string(p.max_attempts));
  if (!(p.retry_roll_deg >= 0 && p.retry_roll_deg <= 90))
    return common::Validation::invalid("retry_roll_deg must be 0..90, got " + std::to_string(p.retry_roll_deg));
  return common::Validation::ok();
}

const char* to_string(BladeResult r) {
  switch (r) {
    case BladeResult::kCutTarget: return "cut_target";
    case BladeResult::kCutOtherPedicel: return "cut_other_pedicel";
    case BladeResult::kClosedOnNothing: return "closed_on_nothing";
    case BladeResult::kJammed: return "jammed";
  }
  return "?";
}

const char* to_string(PickOutcome o) {
  switch (o) {
    case PickOutcome::kPicked: return "picked";
    case PickOutcome::kCutFailure: return "cut_failure";
    case PickOutcome::kCutOther: return "cut_other";
    case PickOutcome::kLeftForHuman: return "left_for_human";
  }
  return "?";
}

PickAttempts::PickAttempts(const PickPose& pose, const HarvestParams& params) : pose_(pose), params_(params) {}

void PickAttempts::note(const std::string& s) { detail_ += s; }

GripperStep PickAttempts::finish(PickOutcome o) {
  done_ = true;
  GripperStep s;
  s.action = GripperStep::Action::kDone;
  s.T_ref_laser = pose_.T_ref_laser;
  s.outcome = o;
  return s;
}

GripperStep PickAttempts::rescan() {
  ++attempt_;
  note("; " + std::to_string(attempt_) + ": ");
  GripperStep s;
  s.action = GripperStep::Action::kRescan;
  s.T_ref_laser = pose_.T_ref_laser;
  return s;
}

GripperStep PickAttempts::after_verification(const Verification& v) {
  if (done_) return finish(PickOutcome::kLeftForHuman);
  if (detail_.empty()) note("1: ");
  note(to_string(v.outcome));
  if (!v.will_cut()) return retry_elsewhere();
  if (v.outcome == Verification::Outcome::kMove) {
    note(" by " + std::to_string(static_cast<int>(std::lround(1000 * v.move.norm()))) + " mm");
    // The laser moves with the hand: the next scan (or the cut) is from there.
    pose_.T_ref_laser = v.T_ref_laser_final;
    pose_.cut_point = v.cut_point;
    if (attempt_ < params_.max_attempts) return rescan();
  }
  GripperStep s;
  s.action = GripperStep::Action::kCut;
  s.T_ref_laser = v.T_ref_laser_final;
  return s;
}

GripperStep PickAttempts::after_cut(BladeResult r) {
  if (done_) return finish(PickOutcome::kLeftForHuman);
  note(std::string(" -> ") + to_string(r));
  switch (r) {
    case BladeResult::kCutTarget: return finish(PickOutcome::kPicked);
    case BladeResult::kJammed: return finish(PickOutcome::kCutFailure);
    case BladeResult::kCutOtherPedicel: return finish(PickOutcome::kCutOther);
    case BladeResult::kClosedOnNothing: break;
  }
  return retry_elsewhere();
}

GripperStep PickAttempts::retry_elsewhere() {
  if (attempt_ >= params_.max_attempts) return finish(PickOutcome::kLeftForHuman);
  // The same cut point seen from another side: the throat stays, the laser turns about the pedicel.
  const double throat_z = (pose_.cut_point - pose_.T_ref_laser.translation()).norm();
  const double sign = attempt_ % 2 == 1 ? 1.0 : -1.0;
  pose_ = rolled(pose_, sign * params_.retry_roll_deg * M_PI / 180.0, throat_z);
  return rescan();
}

}  // namespace tinyline::tomato_reasoning
