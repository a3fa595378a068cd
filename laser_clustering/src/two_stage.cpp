#include "laser_clustering/two_stage.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// An object within this many pixels of the scan's ends may be cut by the field of view.
constexpr int kFovEdgePx = 1;
// Bound on EdgeFilterParams::reference_px (the median works on the stack).
constexpr int kMaxReferencePx = 16;
}

common::Validation validate(const TwoStageParams& p) {
  if (auto v = validate(p.groups); !v.valid) return {false, "groups: " + v.reason};
  if (auto v = validate(p.objects); !v.valid) return {false, "objects: " + v.reason};
  const auto& e = p.edge;
  if (e.edge_width_px < 0) return {false, fmt::format("edge.edge_width_px must be >= 0 (got {})", e.edge_width_px)};
  if (e.reference_px < 1 || e.reference_px > kMaxReferencePx) {
    return {false, fmt::format("edge.reference_px must be in [1, {}] (got {})", kMaxReferencePx, e.reference_px)};
  }
  if (!std::isfinite(e.step_m) || e.step_m < 0.0) {
    return {false, fmt::format("edge.step_m must be finite and >= 0 (got {})", e.step_m)};
  }
  if (!std::isfinite(e.step_per_m) || e.step_per_m < 0.0) {
    return {false, fmt::format("edge.step_per_m must be finite and >= 0 (got {})", e.step_per_m)};
  }
  if (e.min_keep_px < 1) return {false, fmt::format("edge.min_keep_px must be >= 1 (got {})", e.min_keep_px)};
  if (!std::isfinite(e.mixed_step_m) || e.mixed_step_m < 0.0) {
    return {false, fmt::format("edge.mixed_step_m must be finite and >= 0 (got {})", e.mixed_step_m)};
  }
  if (!std::isfinite(e.smooth_step_m) || e.smooth_step_m < 0.0) {
    return {false, fmt::format("edge.smooth_step_m must be finite and >= 0 (got {})", e.smooth_step_m)};
  }
  if (e.smooth_half_width_px < 0) {
    return {false, fmt::format("edge.smooth_half_width_px must be >= 0 (got {})", e.smooth_half_width_px)};
  }
  return {};
}

LineScanClusterer::LineScanClusterer(TwoStageParams params) : params_(params), valid_(validate(params_)) {}

TwoStageResult cluster_line_scan(const LineScan& scan, const TwoStageParams& params) {
  LineScanClusterer c(params);
  return c.run(scan);
}

TwoStageResult LineScanClusterer::run(const LineScan& scan) {
  TwoStageResult out;
  run(scan, out);
  return out;
}

void LineScanClusterer::run(const LineScan& scan, TwoStageResult& out) {
  out.ok = false;
  out.reason.clear();
  out.group_labels.clear();
  out.fate.clear();
  out.smoothed_range_m.clear();
  out.labels.clear();
  out.clusters.clear();
  out.num_groups = 0;
  out.num_edge_dropped = 0;
  if (!valid_.valid) {
    out.reason = valid_.reason;
    return;
  }
  // A sensor's pixel angles are the same scan after scan: check them once.
  const bool same_angles = checked_angle_.size() == scan.angle_rad.size() && !checked_angle_.empty() &&
                           std::memcmp(checked_angle_.data(), scan.angle_rad.data(), checked_angle_.size() * sizeof(double)) == 0;
  if (same_angles && scan.range_m.size() == scan.angle_rad.size() &&
      (scan.reflectance.empty() || scan.reflectance.size() == scan.range_m.size())) {
    // checked before
  } else if (out.reason = check_scan(scan); !out.reason.empty()) {
    checked_angle_.clear();
    return;
  } else {
    checked_angle_.assign(scan.angle_rad.begin(), scan.angle_rad.end());
  }
  const std::size_t n = scan.size();
  const auto& e = params_.edge;
  auto step = [&](double r) { return e.step_m + e.step_per_m * r; };

  // Stage 1: object groups.
  const DbscanResult& groups = groups_;
  dbscan_.run({scan.angle_rad, scan.range_m, {}, {}}, params_.groups, groups_);
  if (!groups.ok) {
    out.reason = "stage 1: " + groups.reason;
    return;
  }
  out.ok = true;
  out.num_groups = groups.num_clusters;
  out.fate.assign(n, PixelFate::kInvalid);  // set per pixel in the run pass below
  out.smoothed_range_m.assign(n, kNaN);

  int run_group = kNoise;  // the group of the run being filtered
  // Stage 2: the edge filter, run by run. A run is a stretch of valid pixels
  // of one group (invalid pixels inside it do not break it).
  // Peels the dragged ends of run positions [first, last] and smooths the rest.
  auto process_piece = [&](const double* r, int first, int last) {
    auto median_of = [&](int from, int to) {  // inclusive run positions, at most kMaxReferencePx values
      const int cnt = to - from + 1;
      // The default reference (3 points) without a selection: the same element nth_element picks.
      if (cnt == 1) return r[from];
      if (cnt == 2) return std::max(r[from], r[from + 1]);
      if (cnt == 3) {
        const double a = r[from], b = r[from + 1], c = r[from + 2];
        return std::max(std::min(a, b), std::min(std::max(a, b), c));
      }
      std::array<double, kMaxReferencePx> v;
      std::copy(r + from, r + to + 1, v.begin());
      std::nth_element(v.begin(), v.begin() + cnt / 2, v.begin() + cnt);
      return v[static_cast<std::size_t>(cnt / 2)];
    };
    int lo = first, hi = last;
    for (int k = 0; k < e.edge_width_px && hi - lo + 1 > e.min_keep_px; ++k) {
      const double ref = median_of(lo + 1, std::min(hi, lo + e.reference_px));
      if (std::abs(r[lo] - ref) <= step(ref)) break;
      out.fate[static_cast<std::size_t>(run_[static_cast<std::size_t>(lo)])] = PixelFate::kEdgeDropped;
      ++lo;
    }
    for (int k = 0; k < e.edge_width_px && hi - lo + 1 > e.min_keep_px; ++k) {
      const double ref = median_of(std::max(lo, hi - e.reference_px), hi - 1);
      if (std::abs(r[hi] - ref) <= step(ref)) break;
      out.fate[static_cast<std::size_t>(run_[static_cast<std::size_t>(hi)])] = PixelFate::kEdgeDropped;
      --hi;
    }
    out.num_edge_dropped += (lo - first) + (last - hi);
    // Smooth the kept points without averaging across a depth step.
    const int h = e.smooth_half_width_px;
    for (int k = lo; k <= hi; ++k) {
      const double c = r[k], limit = e.smooth_step_m + e.step_per_m * c;
      double sum = 0.0;
      int cnt = 0;
      const int j_end = std::min(hi, k + h);
      for (int j = std::max(lo, k - h); j <= j_end; ++j) {
        const bool near = std::abs(r[j] - c) <= limit;
        sum += near ? r[j] : 0.0;
        cnt += near;
      }
      const auto px = static_cast<std::size_t>(run_[static_cast<std::size_t>(k)]);
      out.smoothed_range_m[px] = sum / cnt;
      group_[px] = run_group;
    }
  };
  auto process_run = [&]() {
    const int m = static_cast<int>(run_.size());
    if (m == 0) return;
    // The run's ranges, contiguous.
    range_.resize(run_.size());
    for (std::size_t k = 0; k < run_.size(); ++k) range_[k] = scan.range_m[static_cast<std::size_t>(run_[k])];
    const double* r = range_.data();
    // Mixed pixels inside the run: a pixel between two depths (a pedicel 2 cm
    // before a tomato) reads a range between them and would chain the two in
    // stage 3. It is dropped when its neighbours differ by more than
    // mixed_step_m (+ step_per_m * range) and it lies in the middle of that
    // step (at least a quarter of it from either side); the run is cut there.
    int first = 0;
    for (int k = 1; k + 1 < m; ++k) {
      const double span = r[k + 1] - r[k - 1];
      const double lo_side = std::min(r[k - 1], r[k + 1]), hi_side = std::max(r[k - 1], r[k + 1]);
      const bool mixed = std::abs(span) > e.mixed_step_m + e.step_per_m * lo_side &&
                         r[k] - lo_side >= 0.25 * std::abs(span) && hi_side - r[k] >= 0.25 * std::abs(span);
      if (!mixed) continue;
      out.fate[static_cast<std::size_t>(run_[static_cast<std::size_t>(k)])] = PixelFate::kEdgeDropped;
      ++out.num_edge_dropped;
      if (k - 1 >= first) process_piece(r, first, k - 1);
      first = k + 1;
    }
    if (first <= m - 1) process_piece(r, first, m - 1);
  };
  run_.clear();
  group_.assign(n, -1);  // stage 3's groups: the kept pixels' (process_piece fills them)
  for (std::size_t i = 0; i < n; ++i) {
    const int g = groups.labels[i];
    if (g == kInvalid) continue;
    // Before any edge drop: process_run() only touches pixels before i.
    out.fate[i] = g == kNoise ? PixelFate::kNotGrouped : PixelFate::kKept;
    if (g != run_group) {
      process_run();
      run_.clear();
      run_group = g;
    }
    if (g >= 0) run_.push_back(static_cast<int>(i));
  }
  process_run();

  // Stage 3: small-eps DBSCAN inside each group, on the smoothed ranges.
  const DbscanResult& objects = objects_;
  dbscan_.run({scan.angle_rad, out.smoothed_range_m, {}, group_}, params_.objects, objects_);
  if (!objects.ok) {
    out.ok = false;
    out.reason = "stage 3: " + objects.reason;
    return;
  }
  out.labels.assign(objects.labels.begin(), objects.labels.end());

  // Per-object summaries (the sines and cosines of the angles are the
  // clusterer's cached ones).
  const auto& sin_a = dbscan_.sin_angle();
  const auto& cos_a = dbscan_.cos_angle();
  out.clusters.assign(static_cast<std::size_t>(objects.num_clusters), ScanCluster{});
  std::vector<double>& sum_r2 = sum_r2_;
  std::vector<double>& sum_refl = sum_refl_;
  std::vector<int>& n_refl = n_refl_;
  sum_r2.assign(out.clusters.size(), 0.0);
  sum_refl.assign(out.clusters.size(), 0.0);
  n_refl.assign(out.clusters.size(), 0);
  bool any_valid = false;
  // The sums of a stretch of pixels with one label stay in registers and go
  // back to their cluster when the label changes (an object is one stretch
  // unless something cuts it): the same additions in the same order as
  // adding to the cluster pixel by pixel, without a store and a reload each.
  const bool with_refl = !scan.reflectance.empty();
  int cur = -1, cnt = 0, last = -1, refl_cnt = 0;
  double sx = 0.0, sz = 0.0, sr = 0.0, sr2 = 0.0, srefl = 0.0;
  auto flush = [&]() {
    if (cur < 0) return;
    const auto u = static_cast<std::size_t>(cur);
    auto& c = out.clusters[u];
    c.num_points = cnt;
    c.last_pixel = last;
    c.centroid_xz_m = Eigen::Vector2d(sx, sz);
    c.mean_range_m = sr;
    sum_r2[u] = sr2;
    sum_refl[u] = srefl;
    n_refl[u] = refl_cnt;
  };
  for (std::size_t i = 0; i < n; ++i) {
    any_valid = any_valid || scan.valid(i);
    const int l = out.labels[i];
    if (l < 0) {
      // Dropped and ungrouped pixels are noise to the caller, not invalid.
      if (l == kInvalid && out.fate[i] != PixelFate::kInvalid) out.labels[i] = kNoise;
      continue;
    }
    if (l != cur) {
      flush();
      cur = l;
      const auto u = static_cast<std::size_t>(l);
      auto& c = out.clusters[u];
      if (c.num_points == 0) {
        c.id = l;
        c.group = groups.labels[i];
        c.first_pixel = static_cast<int>(i);
      }
      cnt = c.num_points;
      sx = c.centroid_xz_m.x();
      sz = c.centroid_xz_m.y();
      sr = c.mean_range_m;
      sr2 = sum_r2[u];
      srefl = sum_refl[u];
      refl_cnt = n_refl[u];
    }
    const double rr = out.smoothed_range_m[i];
    last = static_cast<int>(i);
    ++cnt;
    sx += rr * sin_a[i];
    sz += rr * cos_a[i];
    sr += rr;
    sr2 += rr * rr;
    if (with_refl && std::isfinite(scan.reflectance[i])) {
      srefl += scan.reflectance[i];
      ++refl_cnt;
    }
  }
  flush();
  for (std::size_t l = 0; l < out.clusters.size(); ++l) {
    auto& c = out.clusters[l];
    const double k = c.num_points;
    c.centroid_xz_m /= k;
    c.mean_range_m /= k;
    c.range_sd_m = std::sqrt(std::max(0.0, sum_r2[l] / k - c.mean_range_m * c.mean_range_m));
    c.mean_reflectance = n_refl[l] ? sum_refl[l] / n_refl[l] : kNaN;
    const auto f = static_cast<std::size_t>(c.first_pixel), b = static_cast<std::size_t>(c.last_pixel);
    // One pixel's footprint: the mean bearing step around the object.
    const std::size_t lo = f > 0 ? f - 1 : f, hi = b + 1 < n ? b + 1 : b;
    const double pitch = hi > lo ? std::abs(scan.angle_rad[hi] - scan.angle_rad[lo]) / static_cast<double>(hi - lo) : 0.0;
    c.width_m = c.mean_range_m * (std::abs(scan.angle_rad[b] - scan.angle_rad[f]) + pitch);
    c.touches_fov_edge = c.first_pixel <= kFovEdgePx || c.last_pixel >= static_cast<int>(n) - 1 - kFovEdgePx;
    // Occlusion: one of the next two valid pixels beyond the end is in front
    // (two, because the first may be a mixed pixel between the two depths).
    auto in_front = [&](std::size_t edge_pixel, int dir) {
      const double edge_r = out.smoothed_range_m[edge_pixel];
      const double limit = edge_r - (e.mixed_step_m + e.step_per_m * edge_r);
      int seen = 0;
      for (auto j = static_cast<std::ptrdiff_t>(edge_pixel) + dir; j >= 0 && j < static_cast<std::ptrdiff_t>(n) && seen < 2;
           j += dir) {
        const auto u = static_cast<std::size_t>(j);
        if (!scan.valid(u)) continue;
        ++seen;
        if (scan.range_m[u] < limit) return true;
      }
      return false;
    };
    c.occluded_low = in_front(f, -1);
    c.occluded_high = in_front(b, +1);
  }
  out.group_labels.assign(groups.labels.begin(), groups.labels.end());
  if (n == 0) {
    out.reason = "empty scan";
  } else if (!any_valid) {
    out.reason = "no valid pixels";
  }
}

}  // namespace tinyline::laser_clustering
