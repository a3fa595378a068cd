// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/harvest.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
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

namespace {

// A comma-separated list of numbers, each within +-90 (mm or deg).
std::vector<double> numbers(const std::string& key, const std::string& value) {
  std::vector<double> out;
  std::size_t from = 0;
  while (from <= value.size()) {
    const std::size_t comma = std::min(value.find(',', from), value.size());
    const std::string item = value.substr(from, comma - from);
    std::size_t used = 0;
    double v = NAN;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !(std::abs(v) <= 90))
      throw std::invalid_argument("option '" + key + "': '" + item + "' is not a number in [-90, 90]");
    out.push_back(v);
    from = comma + 1;
  }
  return out;
}

}  // namespace

void set_harvest_option(HarvestOptions& o, const std::string& key, const std::string& value) {
  auto flag = [&](bool& f) {
    if (value != "0" && value != "1") throw std::invalid_argument("option '" + key + "' must be 0 or 1");
    f = value == "1";
  };
  if (key == "attempts") {
    if (value.size() != 1 || value[0] < '1' || value[0] > '9')
      throw std::invalid_argument("option 'attempts': '" + value + "' is not a whole number in [1, 9]");
    o.attempts = value[0] - '0';
  } else if (key == "later_attempts_approach_far") {
    flag(o.later_attempts_approach_far);
  } else if (key == "check_blades") {
    flag(o.check_blades);
  } else if (key == "probe_after_laser_refusal") {
    flag(o.probe_after_laser_refusal);
  } else if (key == "probe_shifts_mm" || key == "probe_rolls_deg") {
    const std::vector<double> list = numbers(key, value);
    if (key == "probe_rolls_deg") {
      o.probe.rolls_deg = list;
    } else {
      o.probe.shifts_m.clear();
      for (double mm : list) o.probe.shifts_m.push_back(mm / 1000.0);
    }
  } else if (key == "arbitrate_mm") {
    const std::vector<double> list = numbers(key, value);
    if (list.size() != 1) throw std::invalid_argument("option 'arbitrate_mm': one number");
    o.arbitrate_mm = list[0];
  } else if (key == "vision_when_nothing") {
    flag(o.vision_when_nothing);
  } else if (key == "blade_plane_shifts_mm") {
    o.blade_plane_shifts_m.clear();
    if (value != "none")
      for (double mm : numbers(key, value)) o.blade_plane_shifts_m.push_back(mm / 1000.0);
  } else if (key == "probes") {
    if (value.size() != 1 || value[0] < '0' || value[0] > '9')
      throw std::invalid_argument("option 'probes': '" + value + "' is not a whole number in [0, 9]");
    o.probes = value[0] - '0';
  } else if (key == "pedicel_search") {
    flag(o.pedicel_search);
  } else if (key == "rod_range_bias") {
    flag(o.rod_range_bias);
  } else if (key == "no_cut_tilts_deg") {
    o.no_cut_tilts_deg.clear();
    if (value != "none") o.no_cut_tilts_deg = numbers(key, value);
  } else if (key == "ceiling") {
    flag(o.ceiling);
  } else {
    throw std::invalid_argument("unknown option '" + key + "' (" + kHarvestOptionNames + ")");
  }
}

VerificationOptions harvest_laser(VerificationOptions vo, const HarvestOptions& o) {
  if (!o.rod_range_bias && std::isnan(vo.pedicel_range_bias_m)) vo.pedicel_range_bias_m = 0.0;
  return vo;
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

/// What the harvest believes about a pedicel: the fruit's sphere and the
/// direction from its centre towards the cut, and the rolls already tried.
struct Hypothesis {
  Sphere fruit;
  Eigen::Vector3d direction;
  std::vector<double> tried_rolls;
};

/// The detections whose fruit has fallen: no longer in the blades' way.
std::vector<int> fallen(const Scenario& s, const PipelineResult& r, const HangingTruss& h, double match_m) {
  std::vector<int> gone;
  for (std::size_t k = 0; k < r.tomatoes.size(); ++k)
    if (const int t = matched_truth(s, r.tomatoes[k], match_m); t >= 0 && !h.hanging(t))
      gone.push_back(static_cast<int>(k));
  return gone;
}

/// The reconstructed fruit other than detection `k` and those fallen.
std::vector<Sphere> obstacles(const PipelineResult& r, int k, const std::vector<int>& gone) {
  std::vector<Sphere> out;
  for (std::size_t j = 0; j < r.tomatoes.size(); ++j)
    if (static_cast<int>(j) != k && std::find(gone.begin(), gone.end(), static_cast<int>(j)) == gone.end())
      out.push_back(r.tomatoes[j].fit.sphere);
  return out;
}

/// The best cut that fits the blades, from a roll not yet tried when there
/// is one (another side may show what the last did not); nullopt: none fits.
std::optional<CutCandidate> next_cut(const Hypothesis& hyp, const std::vector<Sphere>& others,
                                     const PickPoseParams& pp) {
  const std::vector<CutCandidate> all = cut_candidates(hyp.fruit, hyp.direction, others, pp);
  std::optional<CutCandidate> any;
  for (const CutCandidate& c : all) {
    if (!c.fits(pp)) break;  // the fitting ones come first
    const bool tried = std::any_of(hyp.tried_rolls.begin(), hyp.tried_rolls.end(),
                                   [&](double r) { return std::abs(r - c.roll_rad) < 0.35; });  // ~20 deg
    if (!tried) return c;
    if (!any) any = c;
  }
  return any;
}

/// next_cut for the hypothesis, else for it tilted by o.no_cut_tilts_deg
/// (six sides each, the smallest tilt first); a tilted fit becomes the
/// hypothesis' direction.
std::optional<CutCandidate> next_cut_tilted(Hypothesis& hyp, const std::vector<Sphere>& others,
                                            const PickPoseParams& pp, const std::vector<double>& tilts_deg) {
  if (std::optional<CutCandidate> c = next_cut(hyp, others, pp)) return c;
  const Eigen::Vector3d d = hyp.direction.normalized();
  const Eigen::Vector3d u = d.unitOrthogonal(), w = d.cross(u);
  for (double tilt : tilts_deg) {
    const double a = tilt * M_PI / 180.0;
    for (int side = 0; side < 6; ++side) {
      const double phi = side * M_PI / 3.0;
      Hypothesis tilted = hyp;
      tilted.direction = std::cos(a) * d + std::sin(a) * (std::cos(phi) * u + std::sin(phi) * w);
      if (std::optional<CutCandidate> c = next_cut(tilted, others, pp); c && c->fits(pp)) {
        hyp.direction = tilted.direction;
        return c;
      }
    }
  }
  return std::nullopt;
}

constexpr const char* kFruitInBlades = "a reconstructed fruit in the blades";

/// What the laser's scan at `T_ref_laser` says against closing there, or "".
std::string laser_refusal(VerificationHarness& laser, const HangingTruss& h, const Scenario& s,
                          const Eigen::Isometry3d& T_ref_laser, std::uint64_t key) {
  const BladeCheck b = laser.check_blades(h.world, s, T_ref_laser, key);
  if (b.kind == BladeCheck::Kind::kClear) return "";
  return b.kind == BladeCheck::Kind::kEmpty ? "the laser sees nothing between the blades"
                                            : "the laser sees " + b.what + " between the blades";
}

/// Why the blades must not close at `T_ref_laser`, or "" to close: the box
/// there must clear the reconstructed fruit, the laser must see one thin
/// object and nothing else between the blades, and nothing the blades would
/// jam on in the planes beside (o.blade_plane_shifts_m; one scan each).
std::string refuse_to_close(VerificationHarness& laser, const HangingTruss& h, const Scenario& s,
                            const Eigen::Isometry3d& T_ref_laser, const std::vector<Sphere>& others, std::uint64_t key,
                            const HarvestOptions& o, HarvestTrial& t) {
  const PickPoseParams& pp = laser.options().pose;
  for (const Sphere& f : others)
    if (blade_clearance(T_ref_laser, f, pp) < pp.blades.margin_m) return kFruitInBlades;
  ++t.scans;
  if (std::string why = laser_refusal(laser, h, s, T_ref_laser, key); !why.empty()) return why;
  std::uint64_t k = key;
  for (double dy : o.blade_plane_shifts_m) {
    ++t.scans;
    const BladeCheck b = laser.check_blades(h.world, s, T_ref_laser * Eigen::Translation3d(0.0, dy, 0.0), k += 7);
    if (b.kind == BladeCheck::Kind::kJam) return "the laser sees " + b.what + " beside the blade plane";
  }
  return "";
}

/// Where the blades close after the loop, or why nowhere.
struct Closing {
  std::optional<Eigen::Isometry3d> T_ref_laser;
  std::string why;  ///< the loop's final pose's refusal, when no pose passed
};

/// How `to` differs from `from` on the same pedicel: "+4mm 20deg".
std::string describe_change(const PickPose& from, const PickPose& to) {
  const Eigen::Vector3d axis = from.pedicel_axis.normalized();
  const double shift_mm = 1000 * (to.cut_point - from.cut_point).dot(axis);
  const Eigen::Vector3d z0 = from.T_ref_laser.linear().col(2), z1 = to.T_ref_laser.linear().col(2);
  const double roll_deg = std::atan2(z0.cross(z1).dot(axis), z0.dot(z1)) * 180.0 / M_PI;
  char text[48];
  std::snprintf(text, sizeof text, "%+.0fmm %.0fdeg", shift_mm, roll_deg);
  return text;
}

/// The loop's final pose when the checks pass there; else the first nearby
/// cut on the same pedicel (moved along it, rolled: nearby_cuts) whose
/// blade box clears the fruit and where the laser sees one thin object, at
/// most o.probes more scans.
Closing where_to_close(VerificationHarness& laser, const HangingTruss& h, const Scenario& s, const Verification& v,
                       const Sphere& own, const std::vector<Sphere>& others, std::uint64_t key, const HarvestOptions& o,
                       HarvestTrial& t) {
  const std::string first = refuse_to_close(laser, h, s, v.T_ref_laser_final, others, key, o, t);
  if (first.empty()) return {v.T_ref_laser_final, ""};
  // What the laser saw between the blades lies near any nearby cut too: only a fruit's sphere is dodged.
  if (!o.probe_after_laser_refusal && first != kFruitInBlades) return {std::nullopt, first};
  PickPose at;
  at.tomato = 0;
  at.T_ref_laser = v.T_ref_laser_final;
  at.cut_point = v.cut_point;
  at.pedicel_axis = v.T_ref_laser_final.linear().col(1);
  int probes = 0;
  for (const PickPose& near : nearby_cuts(at, own, others, laser.options().pose, o.probe)) {
    if (probes++ >= o.probes) break;
    const std::uint64_t probe_key = key + 31 * static_cast<std::uint64_t>(probes);
    if (refuse_to_close(laser, h, s, near.T_ref_laser, others, probe_key, o, t).empty()) {
      t.probed += describe_change(at, near);
      return {near.T_ref_laser, ""};
    }
  }
  return {std::nullopt, first};
}

/// Where the blades close at an attempt whose planned (the vision's) cut
/// is `plan` and whose loop ended with `v`, or why nowhere: the vision's
/// cut when the laser's loop found nothing there (o.vision_when_nothing) or
/// moved it far (o.arbitrate_mm) and the checks there pass; else the loop's
/// final pose (where_to_close).
Closing arbitrate(VerificationHarness& laser, const HangingTruss& h, const Scenario& s, const PickPose& plan,
                  const Verification& v, const Sphere& own, const std::vector<Sphere>& others, std::uint64_t key,
                  const HarvestOptions& o, HarvestTrial& t) {
  const bool far = v.will_cut() && o.arbitrate_mm >= 0 && 1000 * (v.cut_point - plan.cut_point).norm() > o.arbitrate_mm;
  const bool lost = !v.will_cut() && o.vision_when_nothing;
  if (!v.will_cut() && !lost) return {std::nullopt, std::string(to_string(v.outcome)) + ": " + v.reason};
  if (far || lost) {
    const std::string why = refuse_to_close(laser, h, s, plan.T_ref_laser, others, key + 23, o, t);
    if (why.empty()) return {plan.T_ref_laser, ""};
    if (lost) return {std::nullopt, std::string(to_string(v.outcome)) + ": " + v.reason};
  }
  if (!o.check_blades) return {v.T_ref_laser_final, ""};
  return where_to_close(laser, h, s, v, own, others, key + 17, o, t);
}

/// "v1l0c1": the throat on the true pedicel at the vision's cut, the loop's
/// final pose and the closing ('-' where there is none).
std::string on_pedicel(const VerificationHarness& laser, const Scenario& s, int truth, const PickPose& plan,
                       const Verification& v, const std::optional<Eigen::Isometry3d>& closed) {
  const auto pedicel = true_pedicels(s)[static_cast<std::size_t>(truth)];
  auto on = [&](const Eigen::Isometry3d& T) {
    return throat_on_pedicel(laser.options(), pedicel, T, nullptr, nullptr) ? '1' : '0';
  };
  std::string out = "v";
  out += on(plan.T_ref_laser);
  out += 'l';
  out += v.will_cut() ? on(v.T_ref_laser_final) : '-';
  out += 'c';
  out += closed ? on(*closed) : '-';
  return out;
}

/// Up to o.attempts attempts at detection `k` (true tomato t.truth), each
/// from a cut that fits the blades; what an attempt's laser saw becomes the
/// next attempt's pedicel hypothesis.
void attempt_pick(VerificationHarness& laser, const Scenario& s, const PipelineResult& r, int k, HangingTruss& h,
                  HarvestTrial& t, const HarvestOptions& o, const CutModel& cut) {
  const PickPoseParams pp = camera_side(laser.options().pose);
  const Tomato& det = r.tomatoes[static_cast<std::size_t>(k)];
  Hypothesis hyp{det.fit.sphere, det.cut.direction, {}};
  const std::vector<int> gone = fallen(s, r, h, o.match_m);
  const std::vector<Sphere> others = obstacles(r, k, gone);
  for (t.attempts = 1; t.attempts <= o.attempts; ++t.attempts) {
    if (t.attempts > 1) t.cuts += ';', t.why += ';', t.probed += ';', t.on_pedicel += ';';
    const std::optional<CutCandidate> plan = next_cut_tilted(hyp, others, pp, o.no_cut_tilts_deg);
    if (!plan) {  // say so, and do not close the blades
      t.cuts += "no_cut";
      t.why += "no cut clears the blades";
      return;
    }
    hyp.tried_rolls.push_back(plan->roll_rad);
    const std::uint64_t key =
        s.seed * 1000 + static_cast<std::uint64_t>(k) + kAttemptSeedStride * static_cast<std::uint64_t>(t.attempts);
    const bool far = laser.options().approach_far || (t.attempts > 1 && o.later_attempts_approach_far);
    std::optional<TrussView> truss;
    if (o.pedicel_search) truss = truss_view(r, k, gone, plan->pose.T_ref_laser);
    const LoopEnd end = laser.closed_loop(h.world, s, plan->pose, std::nullopt, key, far, truss);
    t.scans += end.scans;
    const Verification& v = end.verification;
    // The pedicel is where the laser put the throat: aim the next attempt there.
    if (const Eigen::Vector3d d = v.cut_point - hyp.fruit.centre; v.will_cut() && d.norm() > hyp.fruit.radius_m)
      hyp.direction = d.normalized();
    const Closing closing = arbitrate(laser, h, s, plan->pose, v, hyp.fruit, others, key, o, t);
    t.on_pedicel += on_pedicel(laser, s, t.truth, plan->pose, v, closing.T_ref_laser);
    if (!closing.T_ref_laser) {
      t.cuts += "no_cut";
      t.why += closing.why;
      continue;
    }
    const Eigen::Isometry3d T_world_throat =
        sim::throat_from_laser(s.truss.T_world_camera * *closing.T_ref_laser, pp.throat_z_m);
    if (settle_cut(h, t, cut(h.truss, T_world_throat, t.truth))) return;
  }
  t.attempts = o.attempts;
}

/// The ceiling: cuts along the true pedicel (calyx -> anchor) at every
/// offset and roll the planner may choose, the cutter model deciding; the
/// first that severs the target alone picks it.
void ceiling_pick(const Scenario& s, HangingTruss& h, HarvestTrial& t, const PickPoseParams& pp, const CutModel& cut) {
  const sim::TrussTomato& truth = h.truss.tomatoes[static_cast<std::size_t>(t.truth)];
  const Eigen::Isometry3d T_ref_world = s.truss.T_world_camera.inverse();
  const Eigen::Vector3d calyx = T_ref_world * truth.calyx_m, anchor = T_ref_world * truth.anchor_m;
  const Eigen::Vector3d axis = (anchor - calyx).normalized();
  const double length = (anchor - calyx).norm();
  t.attempts = 1;
  for (double along = 0.002; along < length; along += 0.003) {
    const PickPose straight = picking_pose(calyx + along * axis, axis, pp);
    for (double roll = -90.0; roll <= 90.0; roll += 15.0) {
      const PickPose pose = rolled(straight, roll * M_PI / 180.0, pp.throat_z_m);
      const Eigen::Isometry3d T = sim::throat_from_laser(s.truss.T_world_camera * pose.T_ref_laser, pp.throat_z_m);
      if (cut(h.truss, T, t.truth).result != sim::CutResult::kCutTarget) continue;
      (void)settle_cut(h, t, cut(h.truss, T, t.truth));
      return;
    }
  }
  t.cuts = "no_cut";
  t.why = "no cut along the true pedicel severs it alone";
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
  std::vector<int> order;  // true tomatoes in the pipeline's pick order (each once), detection indices beside
  std::vector<int> detection;
  for (const int k : r.pick_order) {
    const int truth = matched_truth(s, r.tomatoes[static_cast<std::size_t>(k)], o.match_m);
    // Spheres that are no tomato are not picked here.
    if (truth < 0 || std::find(order.begin(), order.end(), truth) != order.end()) continue;
    order.push_back(truth);
    detection.push_back(k);
  }
  if (o.ceiling)  // the ceiling also picks what the vision missed, last
    for (int i = 0; i < static_cast<int>(trials.size()); ++i)
      if (std::find(order.begin(), order.end(), i) == order.end()) order.push_back(i), detection.push_back(-1);
  for (std::size_t n = 0; n < order.size(); ++n) {
    const int truth = order[n];
    if (!h.hanging(truth)) continue;  // a fruit already fallen is not attempted
    HarvestTrial& t = trials[static_cast<std::size_t>(truth)];
    t.pick_rank = static_cast<int>(n);
    if (o.ceiling)
      ceiling_pick(s, h, t, camera_side(laser.options().pose), cut);
    else
      attempt_pick(laser, s, r, detection[n], h, t, o, cut);
    // Picked, or finished by the human helper: it leaves the truss either way.
    if (h.hanging(truth)) h.fall(truth);
  }
  return trials;
}

}  // namespace tinyline::tomato_reasoning::eval
