#include "laser_clustering/pedicel_finder.hpp"

#include <algorithm>
#include <cmath>

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

Validation validate(const PedicelFinderParams& p) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(p.diameter_m)) return {false, fmt::format("diameter_m must be > 0 (got {})", p.diameter_m)};
  if (!positive(p.diameter_sd_m)) return {false, fmt::format("diameter_sd_m must be > 0 (got {})", p.diameter_sd_m)};
  if (!std::isfinite(p.min_width_m) || p.min_width_m < 0.0 || !positive(p.max_width_m) || p.max_width_m <= p.min_width_m) {
    return {false, fmt::format("need 0 <= min_width_m < max_width_m (got {} and {})", p.min_width_m, p.max_width_m)};
  }
  if (p.min_points < 1) return {false, fmt::format("min_points must be >= 1 (got {})", p.min_points)};
  if (!std::isfinite(p.min_range_m) || p.min_range_m < 0.0 || !positive(p.max_range_m) || p.max_range_m <= p.min_range_m) {
    return {false, fmt::format("need 0 <= min_range_m < max_range_m (got {} and {})", p.min_range_m, p.max_range_m)};
  }
  if (!positive(p.search_sd_m)) return {false, fmt::format("search_sd_m must be > 0 (got {})", p.search_sd_m)};
  if (!positive(p.scissors.opening_m)) {
    return {false, fmt::format("scissors.opening_m must be > 0 (got {})", p.scissors.opening_m)};
  }
  if (!std::isfinite(p.scissors.centre_x_m) || !std::isfinite(p.scissors.centre_z_m)) {
    return {false, "scissors.centre_x_m and centre_z_m must be finite"};
  }
  if (!std::isfinite(p.blade_margin_m) || p.blade_margin_m < 0.0 || !std::isfinite(p.depth_tolerance_m) ||
      p.depth_tolerance_m < 0.0) {
    return {false, "blade_margin_m and depth_tolerance_m must be finite and >= 0"};
  }
  return {};
}

PedicelDetection find_pedicel(const LineScan& scan, const TwoStageResult& objects, const PedicelFinderParams& p,
                              const std::optional<PedicelExpectation>& expectation) {
  PedicelDetection d;
  if (auto v = validate(p); !v.valid) {
    d.reason = v.reason;
    return d;
  }
  if (expectation && (!expectation->position_xz_m.allFinite() || !std::isfinite(expectation->sd_m) ||
                      expectation->sd_m <= 0.0)) {
    d.reason = "expectation must have a finite position and sd_m > 0";
    return d;
  }
  if (!objects.ok) {
    d.reason = "clustering failed: " + objects.reason;
    return d;
  }
  if (objects.labels.size() != scan.size()) {
    d.reason = fmt::format("clustering has {} labels for a scan of {} pixels", objects.labels.size(), scan.size());
    return d;
  }

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

  const Eigen::Vector2d expected =
      expectation ? expectation->position_xz_m : Eigen::Vector2d(p.scissors.centre_x_m, p.scissors.centre_z_m);
  const double sd = expectation ? expectation->sd_m : p.search_sd_m;
  int in_range_objects = 0, cut_by_edge = 0;
  for (std::size_t k = 0; k < objects.clusters.size(); ++k) {
    const ScanCluster& c = objects.clusters[k];
    if (c.mean_range_m < p.min_range_m || c.mean_range_m > p.max_range_m) continue;
    ++in_range_objects;
    if (c.num_points < p.min_points || c.width_m < p.min_width_m || c.width_m > p.max_width_m) continue;
    if (c.touches_fov_edge) {  // width unknown: it may be a tomato or a stem cut by the view
      ++cut_by_edge;
      continue;
    }
    PedicelCandidate cand;
    cand.cluster = static_cast<int>(k);
    cand.width_m = c.width_m;
    cand.position_xz_m = c.centroid_xz_m;
    const double zw = (c.width_m - p.diameter_m) / p.diameter_sd_m;
    cand.shape_score = std::exp(-0.5 * zw * zw);
    cand.isolation = (c.occluded_low ? 0.5 : 1.0) * (c.occluded_high ? 0.5 : 1.0);
    const double zp = (c.centroid_xz_m - expected).norm() / sd;
    cand.position_score = std::exp(-0.5 * zp * zp);
    cand.weight = cand.shape_score * cand.isolation * cand.position_score;
    d.candidates.push_back(cand);
  }
  std::stable_sort(d.candidates.begin(), d.candidates.end(),
                   [](const PedicelCandidate& a, const PedicelCandidate& b) { return a.weight > b.weight; });
  if (d.candidates.empty()) {
    if (cut_by_edge > 0) {
      d.outcome = PedicelOutcome::kOutOfView;
      d.reason = fmt::format("the only pedicel-sized object{} cut by the edge of the field of view",
                             cut_by_edge > 1 ? "s are" : " is");
    } else {
      d.outcome = PedicelOutcome::kNothingToCut;
      d.reason = fmt::format("{} object{} in range, none pedicel-like", in_range_objects, in_range_objects == 1 ? "" : "s");
    }
    return d;
  }

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
  return d;
}

}  // namespace tinyline::laser_clustering
