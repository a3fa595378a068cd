// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/harvest.hpp"

#include <stdexcept>

#include "picking.hpp"

namespace tinyline::tomato_reasoning::eval {

const char* to_string(HarvestOutcome o) {
  switch (o) {
    case HarvestOutcome::kPickedFirst: return "picked_1";
    case HarvestOutcome::kPickedSecond: return "picked_2";
    case HarvestOutcome::kLeftForHuman: return "left_for_human";
    case HarvestOutcome::kCutFailure: return "cut_failure";
    case HarvestOutcome::kKnockedOff: return "knocked_off";
  }
  return "?";
}

void HarvestCounts::add(const HarvestTrial& t) {
  ++trials;
  detected += t.detected;
  picked_first += t.outcome == HarvestOutcome::kPickedFirst;
  picked_second += t.outcome == HarvestOutcome::kPickedSecond;
  left_for_human += t.outcome == HarvestOutcome::kLeftForHuman;
  cut_failures += t.outcome == HarvestOutcome::kCutFailure;
  knocked_off += t.outcome == HarvestOutcome::kKnockedOff;
}

void set_harvest_option(HarvestOptions& o, const std::string& key, const std::string& value) {
  if (key == "attempts") {
    if (value.size() != 1 || value[0] < '1' || value[0] > '9')
      throw std::invalid_argument("option 'attempts': '" + value + "' is not a whole number in [1, 9]");
    o.attempts = value[0] - '0';
  } else if (key == "later_attempts_approach_far") {
    if (value != "0" && value != "1")
      throw std::invalid_argument("option 'later_attempts_approach_far' must be 0 or 1");
    o.later_attempts_approach_far = value == "1";
  } else {
    throw std::invalid_argument("unknown option '" + key + "' (attempts, later_attempts_approach_far)");
  }
}

HarvestCounts& HarvestCounts::operator+=(const HarvestCounts& o) {
  trials += o.trials;
  detected += o.detected;
  picked_first += o.picked_first;
  picked_second += o.picked_second;
  left_for_human += o.left_for_human;
  cut_failures += o.cut_failures;
  knocked_off += o.knocked_off;
  return *this;
}

namespace {

// Attempts are keyed apart from each other's scans (and from the verification's).
constexpr std::uint64_t kAttemptSeedStride = 100'000'007;

/// The truss as it hangs during the harvest: fallen fruit leave both the
/// cutter's record and the world the laser scans.
struct HangingTruss {
  sim::Truss truss;
  sim::World world;
  std::vector<HarvestTrial>& trials;

  /// Fruit `i` falls (cut, or taken by the human helper).
  void fall(int i) {
    (void)sim::drop_tomato(world, truss, i);
    sim::drop_tomato(truss, i);
  }
  [[nodiscard]] bool hanging(int i) const { return !sim::dropped(truss, i); }
};

/// One attempt's blade outcome on trial `t`; true when the trial is over.
bool settle_cut(HangingTruss& h, HarvestTrial& t, const sim::CutOutcome& c) {
  t.cuts += sim::to_string(c.result);
  for (int i : c.severed) {
    if (i == t.truth || !h.hanging(i)) continue;
    h.fall(i);  // a neighbour's pedicel was in the blades: that fruit falls unpicked
    h.trials[static_cast<std::size_t>(i)].outcome = HarvestOutcome::kKnockedOff;
  }
  switch (c.result) {
    case sim::CutResult::kCutTarget:
      t.outcome = t.attempts == 1 ? HarvestOutcome::kPickedFirst : HarvestOutcome::kPickedSecond;
      return true;
    case sim::CutResult::kJammed:
      t.outcome = HarvestOutcome::kCutFailure;
      t.jammed_on = c.object;
      return true;
    case sim::CutResult::kCutOtherPedicel:
    case sim::CutResult::kClosedOnNothing: return false;
  }
  return false;
}

/// Up to o.attempts attempts at detection `k` (true tomato t.truth).
void attempt_pick(VerificationHarness& laser, const Scenario& s, const PipelineResult& r, int k, HangingTruss& h,
                  HarvestTrial& t, const HarvestOptions& o, const CutModel& cut) {
  PickPose pose = picking_pose(r, k, camera_side(laser.options().pose));
  if (!pose.ok()) return;  // left for a human
  std::optional<laser_clustering::PedicelExpectation> belief;
  for (t.attempts = 1; t.attempts <= o.attempts; ++t.attempts) {
    const std::uint64_t key =
        s.seed * 1000 + static_cast<std::uint64_t>(k) + kAttemptSeedStride * static_cast<std::uint64_t>(t.attempts);
    const bool far = laser.options().approach_far || (t.attempts > 1 && o.later_attempts_approach_far);
    const LoopEnd end = laser.closed_loop(h.world, s, pose, belief, key, far);
    t.scans += end.scans;
    if (t.attempts > 1) t.cuts += ';';
    // The next attempt scans again from where this one left the hand.
    pose.T_ref_laser = end.verification.T_ref_laser_final;
    pose.cut_point = end.verification.cut_point;
    belief = end.belief;
    if (!end.verification.will_cut()) {
      t.cuts += "no_cut";
      continue;
    }
    const Eigen::Isometry3d T_world_throat = sim::throat_from_laser(
        s.truss.T_world_camera * end.verification.T_ref_laser_final, laser.options().pose.throat_z_m);
    if (settle_cut(h, t, cut(h.truss, T_world_throat, t.truth))) return;
  }
  t.attempts = o.attempts;
}

}  // namespace

std::vector<HarvestTrial> harvest(VerificationHarness& laser, const Scenario& s, const PipelineResult& r,
                                  const HarvestOptions& o, const CutModel& cut_model) {
  std::vector<HarvestTrial> trials(s.truss.tomatoes.size());
  for (std::size_t i = 0; i < trials.size(); ++i) {
    trials[i].complexity = static_cast<char>(s.complexity);
    trials[i].seed = s.seed;
    trials[i].truth = static_cast<int>(i);
  }
  for (const auto& det : r.tomatoes)
    if (const int t = matched_truth(s, det, o.match_m); t >= 0) trials[static_cast<std::size_t>(t)].detected = true;
  const CutModel cut =
      cut_model ? cut_model : CutModel([&o](const sim::Truss& truss, const Eigen::Isometry3d& T, int target) {
        return sim::close_blades(truss, T, o.blades, target);
      });
  HangingTruss h{s.truss, s.world, trials};
  for (int rank = 0; rank < static_cast<int>(r.pick_order.size()); ++rank) {
    const int k = r.pick_order[static_cast<std::size_t>(rank)];
    const int truth = matched_truth(s, r.tomatoes[static_cast<std::size_t>(k)], o.match_m);
    // Spheres that are no tomato are not picked here; a fruit already
    // fallen or attempted is not attempted again.
    if (truth < 0 || !h.hanging(truth) || trials[static_cast<std::size_t>(truth)].pick_rank >= 0) continue;
    HarvestTrial& t = trials[static_cast<std::size_t>(truth)];
    t.pick_rank = rank;
    attempt_pick(laser, s, r, k, h, t, o, cut);
    // Picked, or finished by the human helper: it leaves the truss either way.
    if (h.hanging(truth)) h.fall(truth);
  }
  return trials;
}

}  // namespace tinyline::tomato_reasoning::eval
