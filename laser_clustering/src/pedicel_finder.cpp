// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/pedicel_finder.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

const char* to_string(PedicelOutcome o) {
  switch (o) {
    case PedicelOutcome::kCutHere: return "cut_here";
    case PedicelOutcome::kMove: return "move";
    case PedicelOutcome::kNothingToCut: return "nothing_to_cut";
    case PedicelOutcome::kOutOfView: return "out_of_view";
    case PedicelOutcome::kInvalidInput: return "invalid_input";
  }
  return "unknown";
}

common::Validation validate(const PedicelFinderParams& p) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(p.diameter_m)) return {false, fmt::format("diameter_m must be > 0 (got {})", p.diameter_m)};
  if (!positive(p.diameter_sd_m)) return {false, fmt::format("diameter_sd_m must be > 0 (got {})", p.diameter_sd_m)};
  if (!std::isfinite(p.min_width_m) || p.min_width_m < 0.0 || !positive(p.max_width_m) ||
      p.max_width_m <= p.min_width_m) {
    return {false, fmt::format("need 0 <= min_width_m < max_width_m (got {} and {})", p.min_width_m, p.max_width_m)};
  }
  if (p.min_points < 1) return {false, fmt::format("min_points must be >= 1 (got {})", p.min_points)};
  if (!std::isfinite(p.min_range_m) || p.min_range_m < 0.0 || !positive(p.max_range_m) ||
      p.max_range_m <= p.min_range_m) {
    return {false, fmt::format("need 0 <= min_range_m < max_range_m (got {} and {})", p.min_range_m, p.max_range_m)};
  }
  if (!positive(p.search_sd_m)) return {false, fmt::format("search_sd_m must be > 0 (got {})", p.search_sd_m)};
  if (!positive(p.scissors.opening_m)) {
    return {false, fmt::format("scissors.opening_m must be > 0 (got {})", p.scissors.opening_m)};
  }
  if (!std::isfinite(p.scissors.centre_x_m) || !std::isfinite(p.scissors.centre_z_m)) {
    return {false, "scissors.centre_x_m and centre_z_m must be finite"};
  }
  if (!(p.layout_miss_factor > 0.0 && p.layout_miss_factor <= 1.0) ||
      !(p.layout_extra_factor > 0.0 && p.layout_extra_factor <= 1.0)) {
    return {false, fmt::format("layout_miss_factor and layout_extra_factor must be in (0, 1] (got {} and {})",
                               p.layout_miss_factor, p.layout_extra_factor)};
  }
  if (!positive(p.recentre_sd_m)) return {false, fmt::format("recentre_sd_m must be > 0 (got {})", p.recentre_sd_m)};
  if (!std::isfinite(p.blade_margin_m) || p.blade_margin_m < 0.0 || !std::isfinite(p.depth_tolerance_m) ||
      p.depth_tolerance_m < 0.0) {
    return {false, "blade_margin_m and depth_tolerance_m must be finite and >= 0"};
  }
  return {};
}

namespace {

// Whether an expected pedicel at q could be seen: inside the field of view
// and the range limits, not within a few pixels of the view's edge (a cut
// object is no candidate), and not behind something nearer on its bearing
// (a tomato in front). An expected pedicel that could not be seen may be
// missing without blame.
class Visibility {
 public:
  Visibility(const LineScan& scan, const PedicelFinderParams& p)
      : scan_(scan),
        p_(p),
        lo_(scan.angle_rad.front()),
        hi_(scan.angle_rad.back()),
        rising_(scan.angle_rad.back() > scan.angle_rad.front()),
        npx_(static_cast<std::ptrdiff_t>(scan.size())) {
    if (lo_ > hi_) std::swap(lo_, hi_);
  }

  bool operator()(const Eigen::Vector2d& q) const {
    constexpr std::ptrdiff_t kEdgePx = 3, kNearPx = 2;
    const double angle = std::atan2(q.x(), q.y()), range = q.norm();
    if (!(angle > lo_ && angle < hi_) || range < p_.min_range_m || range > p_.max_range_m) return false;
    const auto& a = scan_.angle_rad;
    const auto it = rising_ ? std::lower_bound(a.begin(), a.end(), angle)
                            : std::lower_bound(a.begin(), a.end(), angle, std::greater<>());
    const std::ptrdiff_t i = it - a.begin();
    if (i < kEdgePx || i >= npx_ - kEdgePx) return false;
    for (std::ptrdiff_t k = std::max<std::ptrdiff_t>(0, i - kNearPx); k <= std::min(npx_ - 1, i + kNearPx); ++k) {
      const auto u = static_cast<std::size_t>(k);
      if (scan_.valid(u) && scan_.range_m[u] < range - p_.occlusion_margin_m) return false;
    }
    return true;
  }

 private:
  const LineScan& scan_;
  const PedicelFinderParams& p_;
  double lo_, hi_;
  bool rising_;
  std::ptrdiff_t npx_;
};

// The shift that moves the vision's layout onto candidate j: matched to
// the other candidates (nearest within 3 sd), refitted on the matches,
// matched again. `nearest` is scratch (one per neighbour).
Eigen::Vector2d layout_shift(const std::vector<PedicelCandidate>& cands, std::size_t j, const PedicelExpectation& e,
                             std::vector<int>& nearest) {
  const double gate2 = 9.0 * e.neighbour_sd_m * e.neighbour_sd_m;  // 3 sd: farther is no match
  Eigen::Vector2d shift = cands[j].position_xz_m - e.position_xz_m;
  for (int pass = 0; pass < 2; ++pass) {  // match, refit the shift on the matches, match again
    Eigen::Vector2d sum = cands[j].position_xz_m - e.position_xz_m;
    int pairs = 1;
    for (std::size_t i = 0; i < e.neighbours.size(); ++i) {
      const Eigen::Vector2d q = e.neighbours[i].position_xz_m + shift;
      nearest[i] = -1;
      double best = gate2;
      for (std::size_t k = 0; k < cands.size(); ++k) {
        const double d2 = (cands[k].position_xz_m - q).squaredNorm();
        if (k != j && d2 < best) best = d2, nearest[i] = static_cast<int>(k);
      }
      if (nearest[i] >= 0)
        sum += cands[static_cast<std::size_t>(nearest[i])].position_xz_m - e.neighbours[i].position_xz_m, ++pairs;
    }
    shift = sum / pairs;
  }
  return shift;
}

// The truss layout test: candidate j taken for the target moves the vision's
// layout onto it; the move is then refined on every expected neighbour that
// met a candidate (the target's own expectation is as uncertain as theirs, so
// one pair alone must not fix it). Every expected pedicel that lands in view
// should meet a candidate there (else layout_miss_factor, softly), and every
// other candidate should be one of them (else layout_extra_factor). The
// vision's common offset cancels; what is left is its relative error.
void score_layout(const LineScan& scan, const PedicelExpectation& e, const PedicelFinderParams& p,
                  std::vector<PedicelCandidate>& cands) {
  const double inv_var = 1.0 / (e.neighbour_sd_m * e.neighbour_sd_m);
  auto match = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return std::exp(-0.5 * (a - b).squaredNorm() * inv_var);
  };
  const Visibility in_view(scan, p);
  std::vector<int> nearest(e.neighbours.size());
  std::vector<double> explained(cands.size());
  for (std::size_t j = 0; j < cands.size(); ++j) {
    const Eigen::Vector2d shift = layout_shift(cands, j, e, nearest);
    double score = match(cands[j].position_xz_m, e.position_xz_m + shift);
    std::fill(explained.begin(), explained.end(), 0.0);
    for (const auto& nb : e.neighbours) {
      const Eigen::Vector2d q = nb.position_xz_m + shift;
      double best = 0.0;
      for (std::size_t k = 0; k < cands.size(); ++k) {
        if (k == j) continue;
        const double m = match(cands[k].position_xz_m, q);
        best = std::max(best, m);
        explained[k] = std::max(explained[k], m);
      }
      if (!nb.may_be_absent && in_view(q)) score *= p.layout_miss_factor + (1.0 - p.layout_miss_factor) * best;
    }
    for (std::size_t k = 0; k < cands.size(); ++k) {
      if (k != j) score *= p.layout_extra_factor + (1.0 - p.layout_extra_factor) * explained[k];
    }
    cands[j].layout_score = score;
  }
}

}  // namespace

PedicelExpectation expectation_after_centring(const PedicelFinderParams& p,
                                              const std::optional<PedicelExpectation>& before) {
  PedicelExpectation e;
  e.position_xz_m = Eigen::Vector2d(p.scissors.centre_x_m, p.scissors.centre_z_m);
  e.sd_m = p.recentre_sd_m;
  if (before) {
    // The move put the chosen pedicel where the throat is: whatever the
    // layout expected around the old expected point, it now expects around
    // the throat (the vision's common offset is gone with the move).
    const Eigen::Vector2d shift = e.position_xz_m - before->position_xz_m;
    e.neighbours = before->neighbours;
    for (auto& nb : e.neighbours) nb.position_xz_m += shift;
    e.neighbour_sd_m = before->neighbour_sd_m;
  }
  return e;
}

PedicelExpectation shifted(PedicelExpectation e, const Eigen::Vector2d& by) {
  e.position_xz_m += by;
  for (auto& nb : e.neighbours) nb.position_xz_m += by;
  for (auto& alt : e.alternatives) alt.position_xz_m += by;
  return e;
}

PedicelExpectation expectation_after_move(const PedicelFinderParams& p, const std::optional<PedicelExpectation>& before,
                                          const PedicelDetection& seen, const Eigen::Vector2d& move_xz_m) {
  PedicelExpectation e;
  e.sd_m = p.recentre_sd_m;
  if (seen.candidates.empty() || !(seen.candidates.front().weight > 0.0)) {
    // Nothing was chosen: what was expected moves with the gripper.
    if (before) {
      e = shifted(*before, -move_xz_m);
    } else {
      e.position_xz_m = Eigen::Vector2d(p.scissors.centre_x_m, p.scissors.centre_z_m) - move_xz_m;
      e.sd_m = p.search_sd_m;
    }
    return e;
  }
  const PedicelCandidate& best = seen.candidates.front();
  e.position_xz_m = best.position_xz_m - move_xz_m;
  if (before) {
    // The layout was expected around before's point; it now hangs on the
    // chosen pedicel (the vision's common offset is gone with the choice).
    const Eigen::Vector2d shift = e.position_xz_m - before->position_xz_m;
    e.neighbours = before->neighbours;
    for (auto& nb : e.neighbours) nb.position_xz_m += shift;
    e.neighbour_sd_m = before->neighbour_sd_m;
  }
  // The runners-up stay where the move put them, with their weight against
  // the chosen one's: the next scan, from elsewhere, may see the pedicel
  // that tells them apart (its layout factor).
  for (std::size_t k = 1; k < seen.candidates.size(); ++k) {
    const PedicelCandidate& c = seen.candidates[k];
    if (c.weight > 0.0) e.alternatives.push_back({c.position_xz_m - move_xz_m, c.weight / best.weight});
  }
  return e;
}

PedicelExpectation expectation_after_centring(const PedicelFinderParams& p,
                                              const std::optional<PedicelExpectation>& before,
                                              const PedicelDetection& moved) {
  if (moved.candidates.empty() || !(moved.candidates.front().weight > 0.0))
    return expectation_after_centring(p, before);
  const Eigen::Vector2d throat(p.scissors.centre_x_m, p.scissors.centre_z_m);
  return expectation_after_move(p, before, moved, moved.candidates.front().position_xz_m - throat);
}

namespace {

// Why an expectation cannot be used, or empty.
std::string check_expectation(const PedicelExpectation& e) {
  if (!e.position_xz_m.allFinite() || !std::isfinite(e.sd_m) || e.sd_m <= 0.0) {
    return "expectation must have a finite position and sd_m > 0";
  }
  if (!e.neighbours.empty()) {
    if (!std::isfinite(e.neighbour_sd_m) || e.neighbour_sd_m <= 0.0) {
      return fmt::format("expectation neighbour_sd_m must be > 0 (got {})", e.neighbour_sd_m);
    }
    for (std::size_t i = 0; i < e.neighbours.size(); ++i) {
      if (!e.neighbours[i].position_xz_m.allFinite())
        return fmt::format("expectation neighbour {} has a non-finite position", i);
    }
  }
  if (!(e.gate_sd > 0.0)) return fmt::format("expectation gate_sd must be > 0 (got {})", e.gate_sd);
  for (std::size_t i = 0; i < e.alternatives.size(); ++i) {
    const auto& alt = e.alternatives[i];
    if (!alt.position_xz_m.allFinite() || !(alt.weight > 0.0 && alt.weight <= 1.0)) {
      return fmt::format("expectation alternative {} needs a finite position and a weight in (0, 1] (got {})", i,
                         alt.weight);
    }
  }
  return {};
}

// Why the inputs cannot be used, or empty.
std::string check_inputs(const LineScan& scan, const TwoStageResult& objects, const PedicelFinderParams& p,
                         const std::optional<PedicelExpectation>& expectation) {
  if (auto v = validate(p); !v.valid) return v.reason;
  if (expectation) {
    if (std::string why = check_expectation(*expectation); !why.empty()) return why;
  }
  if (!objects.status.ok()) return "clustering failed: " + objects.status.message;
  if (objects.labels.size() != scan.size()) {
    return fmt::format("clustering has {} labels for a scan of {} pixels", objects.labels.size(), scan.size());
  }
  return {};
}

// Where the pedicel is expected, how sure, and how far a candidate may lie.
struct Prior {
  Eigen::Vector2d expected;
  double sd;
  double gate_sd;  // in sd; infinite without an expectation
};

Prior prior_of(const PedicelFinderParams& p, const std::optional<PedicelExpectation>& expectation) {
  if (!expectation) {
    return {Eigen::Vector2d(p.scissors.centre_x_m, p.scissors.centre_z_m), p.search_sd_m,
            std::numeric_limits<double>::infinity()};
  }
  return {expectation->position_xz_m, expectation->sd_m, expectation->gate_sd};
}

// The objects considered, counted by why they are no candidate.
struct Census {
  int in_range_objects = 0, cut_by_edge = 0, beyond_gate = 0;
  double nearest_beyond_m = std::numeric_limits<double>::infinity();
};

// Where an object's axis is: its centroid moved back along its bearing by
// the thin objects' range bias.
Eigen::Vector2d centre_of(const ScanCluster& c, const PedicelFinderParams& p) {
  const double r = c.centroid_xz_m.norm();
  return r > p.range_bias_m && r > 0.0 ? Eigen::Vector2d(c.centroid_xz_m * ((r - p.range_bias_m) / r))
                                       : c.centroid_xz_m;
}

// Object k as a candidate: its shape, isolation and position scores. Sets
// z_min to its distance to the nearest expected point (or alternative) in sd.
PedicelCandidate candidate_of(const ScanCluster& c, int k, const PedicelFinderParams& p, const Prior& prior,
                              const std::optional<PedicelExpectation>& expectation, double& z_min) {
  PedicelCandidate cand;
  cand.cluster = k;
  cand.width_m = c.width_m;
  cand.position_xz_m = centre_of(c, p);
  const double zw = (c.width_m - p.diameter_m) / p.diameter_sd_m;
  cand.shape_score = std::exp(-0.5 * zw * zw);
  cand.isolation = (c.occluded_low ? 0.5 : 1.0) * (c.occluded_high ? 0.5 : 1.0);
  const double zp = (cand.position_xz_m - prior.expected).norm() / prior.sd;
  z_min = zp;
  cand.position_score = std::exp(-0.5 * zp * zp);
  if (expectation) {
    for (const auto& alt : expectation->alternatives) {
      const double za = (cand.position_xz_m - alt.position_xz_m).norm() / prior.sd;
      z_min = std::min(z_min, za);
      cand.position_score = std::max(cand.position_score, alt.weight * std::exp(-0.5 * za * za));
    }
  }
  return cand;
}

// The pedicel-like objects in range, not cut by the view, within the gate.
Census gather_candidates(const TwoStageResult& objects, const PedicelFinderParams& p, const Prior& prior,
                         const std::optional<PedicelExpectation>& expectation, std::vector<PedicelCandidate>& out) {
  Census n;
  for (std::size_t k = 0; k < objects.clusters.size(); ++k) {
    const ScanCluster& c = objects.clusters[k];
    if (c.mean_range_m < p.min_range_m || c.mean_range_m > p.max_range_m) continue;
    ++n.in_range_objects;
    if (c.num_points < p.min_points || c.width_m < p.min_width_m || c.width_m > p.max_width_m) continue;
    if (c.touches_fov_edge) {  // width unknown: it may be a tomato or a stem cut by the view
      ++n.cut_by_edge;
      continue;
    }
    double z_min = 0.0;
    const PedicelCandidate cand = candidate_of(c, static_cast<int>(k), p, prior, expectation, z_min);
    if (z_min > prior.gate_sd) {
      ++n.beyond_gate;
      n.nearest_beyond_m = std::min(n.nearest_beyond_m, z_min * prior.sd);
      continue;
    }
    out.push_back(cand);
  }
  return n;
}

// Best first, ties in scan order: an insertion sort (a scan holds a few
// candidates; std::stable_sort would allocate its buffer every scan).
void rank(std::vector<PedicelCandidate>& cands) {
  for (auto& cand : cands) cand.weight = cand.shape_score * cand.isolation * cand.position_score * cand.layout_score;
  for (std::size_t i = 1; i < cands.size(); ++i) {
    for (std::size_t j = i; j > 0 && cands[j].weight > cands[j - 1].weight; --j) std::swap(cands[j], cands[j - 1]);
  }
}

// The outcome and reason when no candidate is left.
void explain_no_candidate(const Census& n, const Prior& prior, PedicelDetection& d) {
  if (n.beyond_gate > 0) {
    d.outcome = PedicelOutcome::kNothingToCut;
    d.reason = fmt::format(
        "{} pedicel-like object{} in view, none within {:.3f} m ({} sd) of where the pedicel is expected "
        "(nearest {:.3f} m)",
        n.beyond_gate, n.beyond_gate == 1 ? "" : "s", prior.gate_sd * prior.sd, prior.gate_sd, n.nearest_beyond_m);
  } else if (n.cut_by_edge > 0) {
    d.outcome = PedicelOutcome::kOutOfView;
    d.reason = fmt::format("the only pedicel-sized object{} cut by the edge of the field of view",
                           n.cut_by_edge > 1 ? "s are" : " is");
  } else {
    d.outcome = PedicelOutcome::kNothingToCut;
    d.reason =
        fmt::format("{} object{} in range, none pedicel-like", n.in_range_objects, n.in_range_objects == 1 ? "" : "s");
  }
}

// The best candidate as the detection: where to move or cut, how sure.
void choose_best(const PedicelFinderParams& p, PedicelDetection& d) {
  const PedicelCandidate& best = d.candidates.front();
  double total = 0.0;
  for (const auto& c : d.candidates) total += c.weight;
  d.cluster = best.cluster;
  d.position_xz_m = best.position_xz_m;
  d.width_m = best.width_m;
  d.lateral_offset_m = best.position_xz_m.x() - p.scissors.centre_x_m;
  d.depth_offset_m = best.position_xz_m.y() - p.scissors.centre_z_m;
  d.angle_rad = std::atan2(best.position_xz_m.x(), best.position_xz_m.y()) -
                std::atan2(p.scissors.centre_x_m, p.scissors.centre_z_m);
  // A vanishing total (every candidate far from the expectation) still
  // leaves the best one; its share is then taken as 1/count.
  const double share = total > 0.0 ? best.weight / total : 1.0 / static_cast<double>(d.candidates.size());
  d.confidence = best.shape_score * best.isolation * share;
  const bool between_blades = std::abs(d.lateral_offset_m) <= p.scissors.opening_m / 2 - p.blade_margin_m &&
                              std::abs(d.depth_offset_m) <= p.depth_tolerance_m;
  d.outcome = between_blades ? PedicelOutcome::kCutHere : PedicelOutcome::kMove;
  // A fixed note: the numbers are in the fields, and formatting them would
  // cost more than finding the pedicel.
  d.reason = between_blades ? "pedicel between the blades" : "pedicel in view: move to it";
}

}  // namespace

PedicelDetection find_pedicel(const LineScan& scan, const TwoStageResult& objects, const PedicelFinderParams& p,
                              const std::optional<PedicelExpectation>& expectation) {
  PedicelDetection d;
  if (d.reason = check_inputs(scan, objects, p, expectation); !d.reason.empty()) return d;
  std::size_t in_range = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    in_range += scan.valid(i) && scan.range_m[i] >= p.min_range_m && scan.range_m[i] <= p.max_range_m;
  }
  if (in_range == 0) {
    d.outcome = PedicelOutcome::kOutOfView;
    d.reason = scan.size() == 0 ? "empty scan"
                                : fmt::format("no return between {:.3f} and {:.3f} m ({} valid pixels of {})",
                                              p.min_range_m, p.max_range_m, scan.num_valid(), scan.size());
    return d;
  }
  const Prior prior = prior_of(p, expectation);
  const Census census = gather_candidates(objects, p, prior, expectation, d.candidates);
  if (expectation && !expectation->neighbours.empty()) score_layout(scan, *expectation, p, d.candidates);
  rank(d.candidates);
  if (d.candidates.empty()) {
    explain_no_candidate(census, prior, d);
  } else {
    choose_best(p, d);
  }
  return d;
}

}  // namespace tinyline::laser_clustering
