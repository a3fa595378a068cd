// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/two_stage.hpp"

#include "laser_clustering/param_tables.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "two_stage_steps.hpp"

namespace tinyline::laser_clustering {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// An object within this many pixels of the scan's ends may be cut by the field of view.
constexpr int kFovEdgePx = 1;
}  // namespace

common::Status validate(const TwoStageParams& p) {
  if (auto v = validate(p.groups); !v.ok()) return v.within("groups");
  if (auto v = validate(p.objects); !v.ok()) return v.within("objects");
  // The edge filter's fields are single-field ranges: its table holds them
  // (edge_reference_px at most detail::kMaxReferencePx).
  return common::within_table(p.edge).within("edge");
}

namespace detail {

double reference_median(const double* r, int from, int to) {
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
}

bool is_mixed_pixel(double before, double at, double after, const EdgeFilterParams& e) {
  const double span = after - before;
  const double lo_side = std::min(before, after), hi_side = std::max(before, after);
  return std::abs(span) > e.mixed_step_m + e.step_per_m * lo_side && at - lo_side >= 0.25 * std::abs(span) &&
         hi_side - at >= 0.25 * std::abs(span);
}

EdgePeel peel_dragged_ends(const double* r, int first, int last, const EdgeFilterParams& e) {
  auto step = [&](double ref) { return e.step_m + e.step_per_m * ref; };
  int lo = first, hi = last;
  for (int k = 0; k < e.edge_width_px && hi - lo + 1 > e.min_keep_px; ++k) {
    const double ref = reference_median(r, lo + 1, std::min(hi, lo + e.reference_px));
    if (std::abs(r[lo] - ref) <= step(ref)) break;
    ++lo;
  }
  for (int k = 0; k < e.edge_width_px && hi - lo + 1 > e.min_keep_px; ++k) {
    const double ref = reference_median(r, std::max(lo, hi - e.reference_px), hi - 1);
    if (std::abs(r[hi] - ref) <= step(ref)) break;
    --hi;
  }
  return {lo, hi};
}

double smoothed_range(const double* r, int k, int lo, int hi, const EdgeFilterParams& e) {
  const int h = e.smooth_half_width_px;
  const double c = r[k], limit = e.smooth_step_m + e.step_per_m * c;
  double sum = 0.0;
  int cnt = 0;
  const int j_end = std::min(hi, k + h);
  for (int j = std::max(lo, k - h); j <= j_end; ++j) {
    const bool near = std::abs(r[j] - c) <= limit;
    sum += near ? r[j] : 0.0;
    cnt += near;
  }
  return sum / cnt;
}

}  // namespace detail

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
  reset(out);
  if (!valid_.ok()) {
    out.status = valid_;
    return;
  }
  if (out.status = check_once(scan); !out.status.ok()) return;
  // Stage 1: object groups.
  dbscan_.run({scan.angle_rad, scan.range_m, {}, {}}, params_.groups, groups_);
  if (!groups_.status.ok()) {
    out.status = groups_.status.within("stage 1");
    return;
  }
  out.num_groups = groups_.num_clusters;
  edge_filter(scan, out);
  // Stage 3: small-eps DBSCAN inside each group, on the smoothed ranges.
  dbscan_.run({scan.angle_rad, out.smoothed_range_m, {}, group_}, params_.objects, objects_);
  if (!objects_.status.ok()) {
    out.status = objects_.status.within("stage 3");
    return;
  }
  out.labels.assign(objects_.labels.begin(), objects_.labels.end());
  const bool any_valid = sum_clusters(scan, out);
  for (std::size_t l = 0; l < out.clusters.size(); ++l) finish_cluster(scan, l, out);
  out.group_labels.assign(groups_.labels.begin(), groups_.labels.end());
  if (scan.size() == 0) {
    out.note = "empty scan";
  } else if (!any_valid) {
    out.note = "no valid pixels";
  }
}

void LineScanClusterer::reset(TwoStageResult& out) {
  out.status = {};
  out.note.clear();
  out.group_labels.clear();
  out.fate.clear();
  out.smoothed_range_m.clear();
  out.labels.clear();
  out.clusters.clear();
  out.num_groups = 0;
  out.num_edge_dropped = 0;
}

common::Status LineScanClusterer::check_once(const LineScan& scan) {
  // A sensor's pixel angles are the same scan after scan: check them once.
  const bool same_angles =
      checked_angle_.size() == scan.angle_rad.size() && !checked_angle_.empty() &&
      std::memcmp(checked_angle_.data(), scan.angle_rad.data(), checked_angle_.size() * sizeof(double)) == 0;
  if (same_angles && scan.range_m.size() == scan.angle_rad.size() &&
      (scan.reflectance.empty() || scan.reflectance.size() == scan.range_m.size())) {
    return {};  // checked before
  }
  common::Status status = check_scan(scan);
  if (status.ok()) {
    checked_angle_.assign(scan.angle_rad.begin(), scan.angle_rad.end());
  } else {
    checked_angle_.clear();
  }
  return status;
}

// Stage 2: the edge filter, run by run. A run is a stretch of valid pixels
// of one group (invalid pixels inside it do not break it). Sets every
// pixel's fate, the kept pixels' smoothed ranges and stage 3's groups.
void LineScanClusterer::edge_filter(const LineScan& scan, TwoStageResult& out) {
  const std::size_t n = scan.size();
  out.fate.assign(n, PixelFate::kInvalid);
  out.smoothed_range_m.assign(n, kNaN);
  group_.assign(n, -1);  // stage 3's groups: the kept pixels' (filter_piece fills them)
  run_.clear();
  int run_group = kNoise;  // the group of the run being filtered
  for (std::size_t i = 0; i < n; ++i) {
    const int g = groups_.labels[i];
    if (g == kInvalid) continue;
    // Before any edge drop: filter_run() only touches pixels before i.
    out.fate[i] = g == kNoise ? PixelFate::kNotGrouped : PixelFate::kKept;
    if (g != run_group) {
      filter_run(scan, run_group, out);
      run_.clear();
      run_group = g;
    }
    if (g >= 0) run_.push_back(static_cast<int>(i));
  }
  filter_run(scan, run_group, out);
}

// Mixed pixels inside the run: a pixel between two depths (a pedicel 2 cm
// before a tomato) reads a range between them and would chain the two in
// stage 3. It is dropped and the run is cut there; each piece is filtered.
void LineScanClusterer::filter_run(const LineScan& scan, int group, TwoStageResult& out) {
  const int m = static_cast<int>(run_.size());
  if (m == 0) return;
  // The run's ranges, contiguous.
  range_.resize(run_.size());
  for (std::size_t k = 0; k < run_.size(); ++k) range_[k] = scan.range_m[static_cast<std::size_t>(run_[k])];
  const double* r = range_.data();
  int first = 0;
  for (int k = 1; k + 1 < m; ++k) {
    if (!detail::is_mixed_pixel(r[k - 1], r[k], r[k + 1], params_.edge)) continue;
    out.fate[static_cast<std::size_t>(run_[static_cast<std::size_t>(k)])] = PixelFate::kEdgeDropped;
    ++out.num_edge_dropped;
    if (k - 1 >= first) filter_piece(first, k - 1, group, out);
    first = k + 1;
  }
  if (first <= m - 1) filter_piece(first, m - 1, group, out);
}

// Peels the dragged ends of run positions [first, last] and smooths the
// rest without averaging across a depth step.
void LineScanClusterer::filter_piece(int first, int last, int group, TwoStageResult& out) {
  const double* r = range_.data();
  const auto [lo, hi] = detail::peel_dragged_ends(r, first, last, params_.edge);
  auto pixel = [&](int k) { return static_cast<std::size_t>(run_[static_cast<std::size_t>(k)]); };
  for (int k = first; k < lo; ++k) out.fate[pixel(k)] = PixelFate::kEdgeDropped;
  for (int k = hi + 1; k <= last; ++k) out.fate[pixel(k)] = PixelFate::kEdgeDropped;
  out.num_edge_dropped += (lo - first) + (last - hi);
  for (int k = lo; k <= hi; ++k) {
    out.smoothed_range_m[pixel(k)] = detail::smoothed_range(r, k, lo, hi, params_.edge);
    group_[pixel(k)] = group;
  }
}

// Per-object sums (the sines and cosines of the angles are the clusterer's
// cached ones), and stage-3 invalid pixels that earlier stages saw turned
// into noise. Returns whether any pixel was valid.
bool LineScanClusterer::sum_clusters(const LineScan& scan, TwoStageResult& out) {
  const std::size_t n = scan.size();
  const auto& sin_a = dbscan_.sin_angle();
  const auto& cos_a = dbscan_.cos_angle();
  out.clusters.assign(static_cast<std::size_t>(objects_.num_clusters), ScanCluster{});
  sum_r2_.assign(out.clusters.size(), 0.0);
  sum_refl_.assign(out.clusters.size(), 0.0);
  n_refl_.assign(out.clusters.size(), 0);
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
    sum_r2_[u] = sr2;
    sum_refl_[u] = srefl;
    n_refl_[u] = refl_cnt;
  };
  auto reload = [&](int l, std::size_t i) {
    const auto u = static_cast<std::size_t>(l);
    auto& c = out.clusters[u];
    if (c.num_points == 0) {
      c.id = l;
      c.group = groups_.labels[i];
      c.first_pixel = static_cast<int>(i);
    }
    cnt = c.num_points;
    sx = c.centroid_xz_m.x();
    sz = c.centroid_xz_m.y();
    sr = c.mean_range_m;
    sr2 = sum_r2_[u];
    srefl = sum_refl_[u];
    refl_cnt = n_refl_[u];
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
      reload(l, i);
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
  return any_valid;
}

// From the sums to the means, the width, the field-of-view and the occlusion flags.
void LineScanClusterer::finish_cluster(const LineScan& scan, std::size_t l, TwoStageResult& out) const {
  const std::size_t n = scan.size();
  ScanCluster& c = out.clusters[l];
  const double k = c.num_points;
  c.centroid_xz_m /= k;
  c.mean_range_m /= k;
  c.range_sd_m = std::sqrt(std::max(0.0, sum_r2_[l] / k - c.mean_range_m * c.mean_range_m));
  c.mean_reflectance = n_refl_[l] ? sum_refl_[l] / n_refl_[l] : kNaN;
  const auto f = static_cast<std::size_t>(c.first_pixel), b = static_cast<std::size_t>(c.last_pixel);
  // One pixel's footprint: the mean bearing step around the object.
  const std::size_t lo = f > 0 ? f - 1 : f, hi = b + 1 < n ? b + 1 : b;
  const double pitch = hi > lo ? std::abs(scan.angle_rad[hi] - scan.angle_rad[lo]) / static_cast<double>(hi - lo) : 0.0;
  c.width_m = c.mean_range_m * (std::abs(scan.angle_rad[b] - scan.angle_rad[f]) + pitch);
  c.touches_fov_edge = c.first_pixel <= kFovEdgePx || c.last_pixel >= static_cast<int>(n) - 1 - kFovEdgePx;
  c.occluded_low = detail::in_front(scan, out.smoothed_range_m[f], f, -1, params_.edge);
  c.occluded_high = detail::in_front(scan, out.smoothed_range_m[b], b, +1, params_.edge);
}

namespace detail {

bool in_front(const LineScan& scan, double edge_range_m, std::size_t edge_pixel, int dir, const EdgeFilterParams& e) {
  // Two, because the first may be a mixed pixel between the two depths.
  const auto n = static_cast<std::ptrdiff_t>(scan.size());
  const double limit = edge_range_m - (e.mixed_step_m + e.step_per_m * edge_range_m);
  int seen = 0;
  for (auto j = static_cast<std::ptrdiff_t>(edge_pixel) + dir; j >= 0 && j < n && seen < 2; j += dir) {
    const auto u = static_cast<std::size_t>(j);
    if (!scan.valid(u)) continue;
    ++seen;
    if (scan.range_m[u] < limit) return true;
  }
  return false;
}

}  // namespace detail

}  // namespace tinyline::laser_clustering
