// SPDX-License-Identifier: Apache-2.0
#include "harness.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <variant>

namespace tinyline::laser_clustering::eval {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// A re-scan's noise index: far from every first scan's (the seeds).
constexpr std::uint64_t kRescanSeedStride = 1000003;

// The ground-truth object most of a cluster's pixels hit (kNoObject if none).
sim::ObjectId majority_object(const std::vector<int>& labels, int cluster, const SimulatedScan& s) {
  std::map<sim::ObjectId, int> votes;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] == cluster && s.truth_object[i] != sim::kNoObject) ++votes[s.truth_object[i]];
  }
  sim::ObjectId best = sim::kNoObject;
  int n = 0;
  for (const auto& [id, c] : votes) {
    if (c > n) {
      best = id;
      n = c;
    }
  }
  return best;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  if (i + 1 >= v.size()) return v.back();
  const double f = pos - static_cast<double>(i);
  if (std::isinf(v[i + 1])) return f > 0.0 ? kInfinity : v[i];
  return v[i] * (1.0 - f) + v[i + 1] * f;
}

}  // namespace

Rate wilson(int k, int n) {
  Rate r;
  r.k = k;
  r.n = n;
  if (n <= 0) return r;
  constexpr double z = 1.959963984540054;  // 95 %
  const double p = static_cast<double>(k) / n, z2n = z * z / n;
  const double centre = (p + z2n / 2.0) / (1.0 + z2n);
  const double half = z / (1.0 + z2n) * std::sqrt(p * (1.0 - p) / n + z2n / (4.0 * n));
  r.p = p;
  r.lo = std::max(0.0, centre - half);
  r.hi = std::min(1.0, centre + half);
  return r;
}

std::string object_kind(const TrussScene& scene, sim::ObjectId id) {
  if (id == sim::kNoObject) return "none";
  if (id == scene.truth.target_pedicel) return "target";
  const auto& p = scene.truth.pedicels;
  if (std::find(p.begin(), p.end(), id) != p.end()) return "pedicel";
  const auto& tm = scene.truth.tomatoes;
  if (std::find(tm.begin(), tm.end(), id) != tm.end()) return "tomato";
  const std::string& name = scene.world.object(id).name;
  return name.rfind("leaf", 0) == 0 ? "leaf" : "stem";
}

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::kAligned: return "aligned";
    case Verdict::kWrong: return "wrong";
    case Verdict::kOutOfView: return "out_of_view";
    case Verdict::kMissed: return "missed";
  }
  return "unknown";
}

namespace {

bool moves(const PedicelDetection& d) {
  return d.outcome == PedicelOutcome::kCutHere || d.outcome == PedicelOutcome::kMove;
}

/// What the finder is told before the first scan: the case's expectation
/// and the vision's layout of the truss, when the options use them.
std::optional<PedicelExpectation> first_expectation(const TrussScene& scene, const PedicelFinderParams& finder,
                                                    const TrussEvalOptions& o) {
  const bool layout = o.use_layout && !scene.truth.neighbours_expected.empty();
  if (!o.use_expectation || !(scene.truth.use_expectation || layout)) return std::nullopt;
  // kRandomOffset has no expectation of its own: the throat, with the finder's search spread.
  PedicelExpectation e{scene.truth.expected_xz_m,
                       scene.truth.use_expectation ? scene.truth.expected_sd_m : finder.search_sd_m,
                       {},
                       0.015};
  if (layout) e.neighbours = scene.truth.neighbours_expected;
  return e;
}

/// The first scan's decision, after the tomato look when one was taken.
struct FirstDecision {
  PedicelDetection d;
  std::optional<PedicelExpectation> expectation;
  bool looked = false, registered = false, blind = false;
};

/// Before moving: lower the plane through the target's tomato (y is down),
/// back off out of the sensor's short-range bias, and register the vision's
/// tomatoes there.
TomatoRegistration look_through_tomatoes(Scanner& scanner, const TrussScene& scene, std::uint64_t seed,
                                         const PedicelExpectation& expectation, const TrussEvalOptions& o,
                                         const LookObserver& on_look) {
  const double down = scene.truth.tomatoes_expected.front().centre_m.y();
  std::vector<ExpectedTomato> tomatoes = scene.truth.tomatoes_expected;
  for (auto& t : tomatoes) t.centre_m += Eigen::Vector3d(0.0, -down, o.look_back_m);
  const SimulatedScan look =
      scanner.scan(scene.world, scene.T_world_sensor * Eigen::Translation3d(0.0, down, -o.look_back_m),
                   seed + kRescanSeedStride * 97);
  // The vision's common offset is searched as far as the expectation's
  // own spread allows (3 sd): a tomato-based expectation (kRecognitionError)
  // is good to 1.5 cm, a shifted recognition (kRandomOffset) is not.
  TomatoRegistrationParams registration = o.registration;
  registration.max_shift_m = std::min(registration.max_shift_m, o.registration_search_sd * expectation.sd_m);
  TomatoRegistration reg = register_tomatoes(look.scan, tomatoes, registration);
  if (on_look) on_look(seed, scene, look, tomatoes, reg);
  return reg;
}

/// Nothing pedicel-like where the registered truss puts the target (hidden
/// from here): go there and look again.
void move_blind(PedicelDetection& d, const PedicelExpectation& expectation, const PedicelFinderParams& finder) {
  d.outcome = PedicelOutcome::kMove;
  d.cluster = -1;
  d.candidates.clear();
  d.lateral_offset_m = expectation.position_xz_m.x() - finder.scissors.centre_x_m;
  d.depth_offset_m = expectation.position_xz_m.y() - finder.scissors.centre_z_m;
}

FirstDecision decide_first(Scanner& scanner, const TrussScene& scene, const SimulatedScan& s,
                           const TwoStageResult& objects, std::uint64_t seed, const PedicelFinderParams& finder,
                           const TrussEvalOptions& o, const LookObserver& on_look) {
  FirstDecision f;
  f.expectation = first_expectation(scene, finder, o);
  f.d = find_pedicel(s.scan, objects, finder, f.expectation);
  if (!o.tomato_look || !f.expectation || scene.truth.tomatoes_expected.empty() || !moves(f.d)) return f;
  f.looked = true;
  const TomatoRegistration reg = look_through_tomatoes(scanner, scene, seed, *f.expectation, o, on_look);
  if (!reg.status.ok()) return f;
  f.registered = true;
  f.expectation = shifted(*f.expectation, reg.shift_xz_m);
  f.expectation->sd_m = o.registered_sd_m;
  f.expectation->gate_sd = o.registered_gate_sd;
  f.d = find_pedicel(s.scan, objects, finder, f.expectation);
  if (f.d.outcome == PedicelOutcome::kNothingToCut && o.blind_move) {
    f.blind = true;
    move_blind(f.d, *f.expectation, finder);
  }
  return f;
}

/// Where the closed loop leaves the gripper: its pose, the last move made
/// and the majority object of what it last centred.
struct LoopEnd {
  Eigen::Isometry3d T_world_sensor;
  PedicelDetection last;
  sim::ObjectId chosen = sim::kNoObject;
  int rescans = 0;
};

/// The closed loop (4.5): after a move, scan again from where the gripper
/// now is and re-centre on what the finder sees there.
LoopEnd close_the_loop(Scanner& scanner, LineScanClusterer& clusterer, const TrussScene& scene, std::uint64_t seed,
                       const FirstDecision& first, sim::ObjectId chosen, const PedicelFinderParams& finder,
                       const TrussEvalOptions& o) {
  LoopEnd end{scene.T_world_sensor, first.d, chosen, 0};
  std::optional<PedicelExpectation> belief = first.expectation;
  for (int k = 0; k < o.rescans && end.last.outcome == PedicelOutcome::kMove; ++k) {
    const PedicelDetection& last = end.last;
    end.T_world_sensor = end.T_world_sensor * Eigen::Translation3d(last.lateral_offset_m, 0.0, last.depth_offset_m);
    if (k == 0 && first.blind) {
      // The move went to the registered expectation, not to a seen
      // pedicel: that expectation, its spread and gate, moves along.
      belief = expectation_after_move(finder, belief, last, {last.lateral_offset_m, last.depth_offset_m});
    } else {
      belief = o.carry_runners_up ? expectation_after_centring(finder, belief, last)
                                  : expectation_after_centring(finder, belief);
    }
    const SimulatedScan again =
        scanner.scan(scene.world, end.T_world_sensor, seed + kRescanSeedStride * static_cast<std::uint64_t>(k + 1));
    const TwoStageResult objects_again = clusterer.run(again.scan);
    const PedicelDetection d_again = find_pedicel(again.scan, objects_again, finder, belief);
    ++end.rescans;
    if (!moves(d_again)) {
      // Lost it: the gripper stays where the last move put it.
      end.last.lateral_offset_m = end.last.depth_offset_m = 0.0;
      break;
    }
    end.chosen = majority_object(objects_again.labels,
                                 objects_again.clusters[static_cast<std::size_t>(d_again.cluster)].id, again);
    end.last = d_again;
  }
  return end;
}

/// Aligned when the loop ends on the target between the blades (within the
/// opening less the pedicel's radius, and the depth tolerance).
void score_the_move(TrussTrial& trial, const TrussScene& scene, const LoopEnd& end, const PedicelFinderParams& finder,
                    const TrussEvalOptions& o) {
  trial.chosen_kind = object_kind(scene, trial.chosen);
  // Where the target ends up relative to the throat after the last move.
  const Eigen::Vector3d tgt = end.T_world_sensor.inverse() * (scene.T_world_sensor * scene.truth.target_in_sensor);
  const double lateral = tgt.x() - (finder.scissors.centre_x_m + end.last.lateral_offset_m);
  const double depth = tgt.z() - (finder.scissors.centre_z_m + end.last.depth_offset_m);
  trial.lateral_error_m = lateral;
  const bool between = std::abs(lateral) <= finder.scissors.opening_m / 2 - scene.truth.target_radius_m &&
                       std::abs(depth) <= o.depth_tolerance_m;
  trial.verdict = trial.chosen == scene.truth.target_pedicel && between ? Verdict::kAligned : Verdict::kWrong;
}

/// Geometric ambiguity: another pedicel's axis crosses the laser plane nearer
/// the expected point than the target's.
bool neighbour_nearer(const TrussScene& scene, const Eigen::Vector2d& expected) {
  const Eigen::Isometry3d T_sensor_world = scene.T_world_sensor.inverse();
  const Eigen::Vector3d& tgt = scene.truth.target_in_sensor;
  const double target_d = (Eigen::Vector2d(tgt.x(), tgt.z()) - expected).norm();
  bool nearer = false;
  for (const auto id : scene.truth.pedicels) {
    if (id == scene.truth.target_pedicel) continue;
    const auto& rod = std::get<sim::RodShape>(scene.world.object(id).shape);
    const Eigen::Vector3d p0 = T_sensor_world * rod.p0, p1 = T_sensor_world * rod.p1;
    if ((p0.y() < 0.0) == (p1.y() < 0.0)) continue;  // does not reach the plane
    const Eigen::Vector3d c = p0 + (-p0.y() / (p1.y() - p0.y())) * (p1 - p0);
    if ((Eigen::Vector2d(c.x(), c.z()) - expected).norm() < target_d) nearer = true;
  }
  return nearer;
}

/// The counts behind TrussResult's rates.
struct TrussTally {
  int counts[4] = {0, 0, 0, 0};
  int ambiguous = 0, unambiguous = 0, aligned_unambiguous = 0;

  void add(const TrussTrial& t) {
    ++counts[static_cast<int>(t.verdict)];
    ambiguous += t.neighbour_nearer;
    if (!t.neighbour_nearer) {
      ++unambiguous;
      aligned_unambiguous += t.verdict == Verdict::kAligned;
    }
  }
  void rates(TrussResult& out, int trials) const {
    out.aligned = wilson(counts[0], trials);
    out.wrong = wilson(counts[1], trials);
    out.out_of_view = wilson(counts[2], trials);
    out.missed = wilson(counts[3], trials);
    out.ambiguous = wilson(ambiguous, trials);
    out.aligned_unambiguous = wilson(aligned_unambiguous, unambiguous);
  }
};

}  // namespace

TrussResult run_truss_case(TrussCase c, Scanner& scanner, int trials, std::uint64_t seed0, const TrussEvalOptions& o,
                           const TrussObserver& on_trial, const LookObserver& on_look) {
  TrussResult out;
  PedicelFinderParams finder = o.finder;
  finder.scissors.centre_x_m = 0.0;
  finder.scissors.centre_z_m = o.scene.throat_z_m;
  LineScanClusterer clusterer(o.clustering);
  TrussTally tally;
  for (int t = 0; t < trials; ++t) {
    const std::uint64_t seed = seed0 + static_cast<std::uint64_t>(t);
    const TrussScene scene = make_truss_scene(c, seed, o.scene);
    const SimulatedScan s = scanner.scan(scene.world, scene.T_world_sensor, seed);
    const TwoStageResult objects = clusterer.run(s.scan);
    const FirstDecision first = decide_first(scanner, scene, s, objects, seed, finder, o, on_look);
    const PedicelDetection& d = first.d;

    TrussTrial trial;
    trial.seed = seed;
    trial.outcome = d.outcome;
    trial.confidence = d.confidence;
    trial.looked = first.looked;
    trial.registered = first.registered;
    int target_pixels = 0;
    for (const auto id : s.truth_object) target_pixels += id == scene.truth.target_pedicel;
    trial.target_visible = target_pixels >= 2;
    if (moves(d)) {
      const sim::ObjectId chosen =
          d.cluster >= 0 ? majority_object(objects.labels, objects.clusters[static_cast<std::size_t>(d.cluster)].id, s)
                         : sim::kNoObject;
      const LoopEnd end = close_the_loop(scanner, clusterer, scene, seed, first, chosen, finder, o);
      trial.chosen = end.chosen;
      trial.rescans = end.rescans;
      score_the_move(trial, scene, end, finder, o);
      if (first.blind && trial.chosen == sim::kNoObject) {  // the look from there found nothing either: no cut
        trial.outcome = PedicelOutcome::kNothingToCut;
        trial.verdict = trial.target_visible ? Verdict::kMissed : Verdict::kOutOfView;
      }
    } else {
      trial.chosen_kind = "none";
      trial.verdict = trial.target_visible ? Verdict::kMissed : Verdict::kOutOfView;
    }
    trial.neighbour_nearer = neighbour_nearer(
        scene, first.expectation ? scene.truth.expected_xz_m
                                 : Eigen::Vector2d(finder.scissors.centre_x_m, finder.scissors.centre_z_m));
    tally.add(trial);
    if (on_trial) on_trial(trial, scene, s, objects, d);
    out.trials.push_back(std::move(trial));
  }
  tally.rates(out, trials);
  return out;
}

namespace {

// IoU of the stick's pure pixels and the cluster holding most of them; mixed
// pixels (footprint over stick and panel) belong to neither side.
double stick_iou(const std::vector<int>& labels, const SimulatedScan& s, sim::ObjectId stick) {
  std::map<int, int> votes;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (s.truth_object[i] == stick && !s.truth_mixed[i] && labels[i] >= 0) ++votes[labels[i]];
  }
  if (votes.empty()) return 0.0;
  const int best =
      std::max_element(votes.begin(), votes.end(), [](auto& a, auto& b) { return a.second < b.second; })->first;
  int inter = 0, uni = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (s.truth_mixed[i]) continue;
    const bool a = s.truth_object[i] == stick, b = labels[i] == best;
    inter += a && b;
    uni += a || b;
  }
  return uni ? static_cast<double>(inter) / uni : 0.0;
}

}  // namespace

StickResult run_stick_case(Scanner& scanner, int trials, std::uint64_t seed0, const StickEvalOptions& o,
                           const StickObserver& on_trial) {
  StickResult out;
  int with = 0, without = 0;
  ReflectanceClusteringParams pw = o.clustering, pd = o.clustering;
  pw.use_reflectance = true;
  pd.use_reflectance = false;
  for (int t = 0; t < trials; ++t) {
    const std::uint64_t seed = seed0 + static_cast<std::uint64_t>(t);
    const StickScene scene = make_stick_scene(seed, o.scene);
    const SimulatedScan s = scanner.scan(scene.world, scene.T_world_sensor, seed);
    const auto rw = cluster_by_reflectance(s.scan, pw);
    const auto rd = cluster_by_reflectance(s.scan, pd);
    StickTrial trial;
    trial.seed = seed;
    trial.iou_reflectance = rw.status.ok() ? stick_iou(rw.labels, s, scene.stick) : 0.0;
    trial.iou_distance_only = rd.status.ok() ? stick_iou(rd.labels, s, scene.stick) : 0.0;
    with += trial.iou_reflectance >= o.min_iou;
    without += trial.iou_distance_only >= o.min_iou;
    if (on_trial) on_trial(trial, scene, s, rw, rd);
    out.trials.push_back(trial);
  }
  out.reflectance_correct = wilson(with, trials);
  out.distance_only_correct = wilson(without, trials);
  return out;
}

WrenchResult run_wrench_case(Scanner& scanner, int trials, std::uint64_t seed0, const WrenchEvalOptions& o,
                             const WrenchObserver& on_trial) {
  WrenchResult out;
  std::vector<double> err, step_err;
  int within = 0, found = 0;
  for (int t = 0; t < trials; ++t) {
    const std::uint64_t seed = seed0 + static_cast<std::uint64_t>(t);
    const WrenchScene scene = make_wrench_scene(seed, o.scene);
    std::vector<AlignmentSample> sweep;
    std::uint64_t k = 0;
    for (double p = o.sweep_from_deg; p <= o.sweep_to_deg + 1e-9; p += o.sweep_step_deg, ++k) {
      const SimulatedScan s = scanner.scan(scene.world, scene.T_world_sensor(p * kDeg), seed * 1000 + k);
      const SurfaceReflectance r = surface_reflectance(s.scan, o.surface);
      if (r.status.ok()) sweep.push_back({p * kDeg, r.reflectance});
    }
    const AlignmentResult a = find_alignment(sweep, o.alignment);
    WrenchTrial trial;
    trial.seed = seed;
    trial.outcome = a.outcome;
    trial.true_pitch_rad = scene.true_pitch_rad;
    trial.best_pitch_rad = a.best_pitch_rad;
    const bool ok = a.outcome == AlignmentOutcome::kFound;
    trial.error_rad = ok ? std::abs(a.best_pitch_rad - scene.true_pitch_rad) : kInfinity;
    if (!sweep.empty()) {
      const auto best = std::max_element(sweep.begin(), sweep.end(),
                                         [](const auto& x, const auto& y) { return x.reflectance < y.reflectance; });
      trial.step_error_rad = std::abs(best->pitch_rad - scene.true_pitch_rad);
    } else {
      trial.step_error_rad = kInfinity;
    }
    found += ok;
    within += trial.error_rad <= 1.0 * kDeg;
    err.push_back(trial.error_rad / kDeg);
    step_err.push_back(trial.step_error_rad / kDeg);
    if (on_trial) on_trial(trial, sweep);
    out.trials.push_back(trial);
  }
  out.median_error_deg = quantile(err, 0.5);
  out.p90_error_deg = quantile(err, 0.9);
  out.median_step_error_deg = quantile(step_err, 0.5);
  out.within_1deg = wilson(within, trials);
  out.found = wilson(found, trials);
  return out;
}

}  // namespace tinyline::laser_clustering::eval
