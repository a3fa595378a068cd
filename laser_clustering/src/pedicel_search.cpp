// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/pedicel_search.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

common::Validation validate(const PedicelSearchParams& p) {
  if (p.heights_m.empty()) return {false, "heights_m must hold at least one height"};
  for (double h : p.heights_m) {
    if (!std::isfinite(h)) return {false, "heights_m must be finite"};
  }
  if (!(p.link_m > 0.0) || !std::isfinite(p.link_m))
    return {false, fmt::format("link_m must be > 0 (got {})", p.link_m)};
  if (!(p.slope_sd > 0.0) || !(p.max_slope > 0.0) || !std::isfinite(p.max_slope)) {
    return {false, fmt::format("slope_sd and max_slope must be > 0 (got {}, {})", p.slope_sd, p.max_slope)};
  }
  if (!(p.miss_factor > 0.0 && p.miss_factor <= 1.0)) {
    return {false, fmt::format("miss_factor must be in (0, 1] (got {})", p.miss_factor)};
  }
  if (p.min_planes < 1) return {false, fmt::format("min_planes must be >= 1 (got {})", p.min_planes)};
  return {true, {}};
}

namespace {

// A candidate of one plane, at its height.
struct Seen {
  std::size_t plane = 0;
  double height_m = 0.0;
  Eigen::Vector2d xz = Eigen::Vector2d::Zero();
  double quality = 0.0;  // shape * isolation
};

struct Line {
  Eigen::Vector2d at0 = Eigen::Vector2d::Zero();
  Eigen::Vector2d slope = Eigen::Vector2d::Zero();
  [[nodiscard]] Eigen::Vector2d at(double h) const { return at0 + slope * h; }
};

// A plane that could have seen a pedicel: a scan with nothing in the
// working range shows that none crosses it near the throat.
bool in_view(const PedicelDetection& d) { return d.outcome != PedicelOutcome::kInvalidInput; }

std::vector<Seen> gather(std::span<const SweepScan> scans) {
  std::vector<Seen> seen;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    for (const PedicelCandidate& c : scans[k].detection.candidates) {
      seen.push_back({k, scans[k].height_m, c.position_xz_m, c.shape_score * c.isolation});
    }
  }
  return seen;
}

// The hypotheses: a line along the expected direction through every
// candidate, and the line through every pair of candidates of two planes.
std::vector<Line> hypotheses(const std::vector<Seen>& seen, const PedicelSearchParams& p) {
  std::vector<Line> lines;
  for (std::size_t i = 0; i < seen.size(); ++i) {
    lines.push_back({seen[i].xz, Eigen::Vector2d::Zero()});
    for (std::size_t j = i + 1; j < seen.size(); ++j) {
      const double dh = seen[j].height_m - seen[i].height_m;
      if (seen[i].plane == seen[j].plane || std::abs(dh) < 1e-4) continue;
      const Eigen::Vector2d slope = (seen[j].xz - seen[i].xz) / dh;
      if (slope.cwiseAbs().maxCoeff() > p.max_slope) continue;
      lines.push_back({seen[i].xz - slope * seen[i].height_m, slope});
    }
  }
  return lines;
}

// Per plane, the candidate nearest the line within 2 link_m, or -1.
std::vector<int> linked(const Line& line, std::span<const SweepScan> scans, const std::vector<Seen>& seen,
                        const PedicelSearchParams& p) {
  std::vector<int> best(scans.size(), -1);
  std::vector<double> nearest(scans.size(), 2.0 * p.link_m);
  for (std::size_t i = 0; i < seen.size(); ++i) {
    const double d = (line.at(seen[i].height_m) - seen[i].xz).norm();
    if (d <= nearest[seen[i].plane]) {
      nearest[seen[i].plane] = d;
      best[seen[i].plane] = static_cast<int>(i);
    }
  }
  return best;
}

// The least-squares line through the linked candidates (the slope kept
// when they lie in one plane).
Line refit(const Line& line, const std::vector<int>& link, const std::vector<Seen>& seen) {
  double n = 0, sh = 0, shh = 0;
  Eigen::Vector2d sx = Eigen::Vector2d::Zero(), shx = Eigen::Vector2d::Zero();
  for (int i : link) {
    if (i < 0) continue;
    const Seen& s = seen[static_cast<std::size_t>(i)];
    n += 1;
    sh += s.height_m;
    shh += s.height_m * s.height_m;
    sx += s.xz;
    shx += s.height_m * s.xz;
  }
  if (n == 0) return line;
  const double var = shh - sh * sh / n;
  if (n < 2 || var < 1e-8) return {sx / n - line.slope * (sh / n), line.slope};
  const Eigen::Vector2d slope = (shx - sh * sx / n) / var;
  return {(sx - slope * sh) / n, slope};
}

PedicelTrack score(const Line& line, std::span<const SweepScan> scans, const std::vector<Seen>& seen,
                   const PedicelExpectation& e, const PedicelSearchParams& p) {
  PedicelTrack t;
  t.position_xz_m = line.at0;
  t.slope = line.slope;
  const std::vector<int> link = linked(line, scans, seen, p);
  t.support = 1.0;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    if (link[k] < 0) {
      if (in_view(scans[k].detection)) t.support *= p.miss_factor;
      continue;
    }
    const Seen& s = seen[static_cast<std::size_t>(link[k])];
    const double nearest = t.nearest_seen_height_m;
    if (t.planes_seen == 0 || std::abs(s.height_m) < std::abs(nearest) ||
        (std::abs(s.height_m) == std::abs(nearest) && s.height_m > nearest))
      t.nearest_seen_height_m = s.height_m;
    const double z = (line.at(s.height_m) - s.xz).norm() / p.link_m;
    t.support *= std::exp(-0.5 * z * z);
    t.quality += s.quality;
    ++t.planes_seen;
  }
  if (t.planes_seen > 0) t.quality /= t.planes_seen;
  const double zp = (line.at0 - e.position_xz_m).norm() / e.sd_m;
  const double zs = line.slope.norm() / p.slope_sd;
  t.prior =
      zp > e.gate_sd || line.slope.cwiseAbs().maxCoeff() > p.max_slope ? 0.0 : std::exp(-0.5 * (zp * zp + zs * zs));
  t.weight = t.quality * t.support * t.prior;
  return t;
}

// Every hypothesis refitted to its candidates and scored; the distinct
// ones that enough planes see, best first.
std::vector<PedicelTrack> tracks_of(std::span<const SweepScan> scans, const PedicelExpectation& e,
                                    const PedicelSearchParams& p, int min_planes) {
  const std::vector<Seen> seen = gather(scans);
  std::vector<PedicelTrack> all;
  for (const Line& h : hypotheses(seen, p)) {
    const Line fitted = refit(h, linked(h, scans, seen, p), seen);
    const PedicelTrack t = score(fitted, scans, seen, e, p);
    if (t.weight > 0.0 && t.planes_seen >= min_planes) all.push_back(t);
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.weight > b.weight; });
  std::vector<PedicelTrack> distinct;
  for (const PedicelTrack& t : all) {
    const bool same = std::any_of(distinct.begin(), distinct.end(), [&](const PedicelTrack& d) {
      return (d.position_xz_m - t.position_xz_m).norm() < p.link_m;
    });
    if (!same) distinct.push_back(t);
  }
  return distinct;
}

// The chosen track as the detection in the plane at height h.
PedicelDetection detection_of(const std::vector<PedicelTrack>& tracks, const PedicelFinderParams& f, double h) {
  PedicelDetection d;
  double total = 0.0;
  for (const PedicelTrack& t : tracks) {
    PedicelCandidate c;
    c.position_xz_m = t.position_xz_m + t.slope * h;
    c.shape_score = t.quality;
    c.isolation = 1.0;
    c.position_score = t.prior;
    c.layout_score = t.support;
    c.weight = t.weight;
    d.candidates.push_back(c);
    total += t.weight;
  }
  const PedicelTrack& best = tracks.front();
  d.position_xz_m = d.candidates.front().position_xz_m;
  d.lateral_offset_m = d.position_xz_m.x() - f.scissors.centre_x_m;
  d.depth_offset_m = d.position_xz_m.y() - f.scissors.centre_z_m;
  d.angle_rad =
      std::atan2(d.position_xz_m.x(), d.position_xz_m.y()) - std::atan2(f.scissors.centre_x_m, f.scissors.centre_z_m);
  d.confidence = best.quality * best.weight / total;
  const bool between = std::abs(d.lateral_offset_m) <= f.scissors.opening_m / 2 - f.blade_margin_m &&
                       std::abs(d.depth_offset_m) <= f.depth_tolerance_m;
  d.outcome = between ? PedicelOutcome::kCutHere : PedicelOutcome::kMove;
  d.reason = fmt::format("{} in the throat: a track seen in {} plane{}", between ? "pedicel" : "pedicel not",
                         best.planes_seen, best.planes_seen == 1 ? "" : "s");
  return d;
}

}  // namespace

PedicelSearchResult fuse_sweep(std::span<const SweepScan> scans, const PedicelFinderParams& finder,
                               const PedicelExpectation& expected, const PedicelSearchParams& p) {
  PedicelSearchResult r;
  r.planes = static_cast<int>(scans.size());
  const auto base = std::find_if(scans.begin(), scans.end(), [](const SweepScan& s) { return s.height_m == 0.0; });
  if (auto v = validate(p); !v.valid || base == scans.end()) {
    r.detection.reason = !v.valid ? v.reason : "the sweep has no scan at height 0";
    return r;
  }
  const int in_view_planes = static_cast<int>(
      std::count_if(scans.begin(), scans.end(), [](const SweepScan& s) { return in_view(s.detection); }));
  r.tracks = tracks_of(scans, expected, p, std::max(1, std::min(p.min_planes, in_view_planes)));
  if (!r.tracks.empty()) {
    r.cut_height_m = r.tracks.front().nearest_seen_height_m;
    r.detection = detection_of(r.tracks, finder, r.cut_height_m);
    return r;
  }
  r.detection = base->detection;
  const std::size_t seen = gather(scans).size();
  if (seen > 0) {
    r.detection.outcome = PedicelOutcome::kNothingToCut;
    r.detection.candidates.clear();
    r.detection.cluster = -1;
    r.detection.reason = fmt::format("{} pedicel-like object{} in {} planes, none on a pedicel's track seen in {}",
                                     seen, seen == 1 ? "" : "s", r.planes, p.min_planes);
  }
  return r;
}

}  // namespace tinyline::laser_clustering
