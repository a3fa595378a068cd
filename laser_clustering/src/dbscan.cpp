// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/dbscan.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <numeric>

#include <fmt/format.h>

#include "dbscan_internal.hpp"

namespace tinyline::laser_clustering {

common::Status validate(const DbscanParams& p) {
  if (!std::isfinite(p.eps) || p.eps <= 0.0)
    return common::Status::invalid(fmt::format("DbscanParams.eps must be finite and > 0 (got {})", p.eps));
  if (p.min_points < 1)
    return common::Status::invalid(fmt::format("DbscanParams.min_points must be >= 1 (got {})", p.min_points));
  return {};
}

namespace detail {

common::Status check_points_input(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  if (common::Status v = validate(params); !v.ok()) return v;
  if (points.cols() > 0 && points.rows() == 0)
    return common::Status::invalid(
        fmt::format("points have dimension 0 ({} columns of no coordinates)", points.cols()));
  if (points.cols() >= std::numeric_limits<int>::max())
    return common::Status::invalid(
        fmt::format("too many points ({}); at most {}", points.cols(), std::numeric_limits<int>::max() - 1));
  return {};
}

std::size_t mark_valid(const Eigen::Ref<const Eigen::MatrixXd>& points, std::vector<std::uint8_t>& valid) {
  valid.assign(static_cast<std::size_t>(points.cols()), 0);
  std::size_t n = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (points.col(i).allFinite()) {
      valid[static_cast<std::size_t>(i)] = 1;
      ++n;
    }
  }
  return n;
}

void finish(DbscanResult& r) {
  std::size_t core = 0, noise = 0, invalid = 0;
  for (std::size_t i = 0; i < r.labels.size(); ++i) {
    core += r.is_core[i];
    noise += r.labels[i] == kNoise;
    invalid += r.labels[i] == kInvalid;
  }
  finish(r, core, noise, invalid);
}

void finish(DbscanResult& r, std::size_t core, std::size_t noise, std::size_t invalid) {
  r.status = {};
  r.num_core = core;
  r.num_noise = noise;
  r.num_invalid = invalid;
  // Notes only where there is nothing else to report (formatting costs
  // more than clustering a scan).
  if (r.labels.empty()) {
    r.note = "empty input";
  } else if (invalid == r.labels.size()) {
    r.note = fmt::format("no valid points ({} invalid)", invalid);
  }
}

DbscanResult label_from_neighbours(const std::vector<std::uint8_t>& valid, const NeighbourLists& lists,
                                   int min_points) {
  const std::size_t n = valid.size();
  DbscanResult r;
  r.labels.assign(n, kNoise);
  r.is_core.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) {
      r.labels[i] = kInvalid;
    } else if (lists.offset[i + 1] - lists.offset[i] >= static_cast<std::size_t>(min_points)) {
      r.is_core[i] = 1;
    }
  }
  std::vector<int> parent(n), size(n, 1);
  std::iota(parent.begin(), parent.end(), 0);
  DisjointSets sets(parent, size);
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.is_core[i]) continue;
    for (std::size_t k = lists.offset[i]; k < lists.offset[i + 1]; ++k) {
      const int j = lists.nbr[k];
      if (static_cast<std::size_t>(j) > i && r.is_core[static_cast<std::size_t>(j)]) sets.unite(static_cast<int>(i), j);
    }
  }
  // Clusters in the order of their lowest-indexed core point.
  std::vector<int> cluster_of_root(n, -1);
  int clusters = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.is_core[i]) continue;
    int& c = cluster_of_root[static_cast<std::size_t>(sets.find(static_cast<int>(i)))];
    if (c < 0) c = clusters++;
    r.labels[i] = c;
  }
  // Border points: the lowest-numbered cluster among adjacent core points.
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i] || r.is_core[i]) continue;
    int best = kNoise;
    for (std::size_t k = lists.offset[i]; k < lists.offset[i + 1]; ++k) {
      const auto j = static_cast<std::size_t>(lists.nbr[k]);
      if (r.is_core[j] && (best == kNoise || r.labels[j] < best)) best = r.labels[j];
    }
    r.labels[i] = best;
  }
  r.num_clusters = clusters;
  finish(r);
  return r;
}

}  // namespace detail

DbscanResult dbscan_brute_force(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  DbscanResult bad;
  if (bad.status = detail::check_points_input(points, params); !bad.status.ok()) return bad;
  std::vector<std::uint8_t> valid;
  detail::mark_valid(points, valid);
  const double eps2 = params.eps * params.eps;
  const auto n = static_cast<std::size_t>(points.cols());
  detail::NeighbourLists lists;
  lists.offset.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    lists.offset[i] = lists.nbr.size();
    if (!valid[i]) continue;
    for (std::size_t j = 0; j < n; ++j) {
      if (valid[j] &&
          detail::squared_distance(points, static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) <= eps2) {
        lists.nbr.push_back(static_cast<int>(j));
      }
    }
  }
  lists.offset[n] = lists.nbr.size();
  return detail::label_from_neighbours(valid, lists, params.min_points);
}

// ---------------------------------------------------------------------------
// Ordered line scans

namespace {

inline bool pixel_valid(const OrderedScanPoints& s, std::size_t i) {
  constexpr double kMax = std::numeric_limits<double>::max();
  const double r = s.range_m[i], a = s.angle_rad[i];
  // Written so that NaN fails every comparison.
  if (!(r > 0.0 && r <= kMax && a >= -kMax && a <= kMax)) return false;
  if (!s.group.empty() && s.group[i] < 0) return false;
  return s.feature.empty() || std::isfinite(s.feature[i]);
}

std::string check_scan_shape(const OrderedScanPoints& s) {
  if (s.range_m.size() != s.angle_rad.size()) {
    return fmt::format("scan has {} angles but {} ranges", s.angle_rad.size(), s.range_m.size());
  }
  if (!s.feature.empty() && s.feature.size() != s.range_m.size()) {
    return fmt::format("scan has {} ranges but {} feature values", s.range_m.size(), s.feature.size());
  }
  if (!s.group.empty() && s.group.size() != s.range_m.size()) {
    return fmt::format("scan has {} ranges but {} group ids", s.range_m.size(), s.group.size());
  }
  if (s.range_m.size() >= static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    return fmt::format("scan too long ({} pixels)", s.range_m.size());
  }
  return {};
}

}  // namespace

Eigen::MatrixXd to_points(const OrderedScanPoints& s) {
  const std::size_t n = std::min(s.angle_rad.size(), s.range_m.size());
  const bool with_f = !s.feature.empty() && s.feature.size() >= n;
  Eigen::MatrixXd p(with_f ? 3 : 2, static_cast<Eigen::Index>(n));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    if (!pixel_valid(s, i)) {
      p.col(c).setConstant(nan);
      continue;
    }
    p(0, c) = s.range_m[i] * std::sin(s.angle_rad[i]);
    p(1, c) = s.range_m[i] * std::cos(s.angle_rad[i]);
    if (with_f) p(2, c) = s.feature[i];
  }
  return p;
}

DbscanResult OrderedScanDbscan::run(const OrderedScanPoints& scan, const DbscanParams& params) {
  DbscanResult r;
  run(scan, params, r);
  return r;
}

void OrderedScanDbscan::run(const OrderedScanPoints& scan, const DbscanParams& params, DbscanResult& r) {
  r.status = {common::StatusCode::InvalidArgument, {}};
  r.note.clear();
  r.labels.clear();
  r.is_core.clear();
  r.num_clusters = 0;
  r.num_core = r.num_noise = r.num_invalid = 0;
  if (common::Status v = validate(params); !v.ok()) {
    r.status = std::move(v);
    return;
  }
  if (std::string why = check_scan_shape(scan); !why.empty()) {
    r.status = common::Status::invalid(std::move(why));
    return;
  }
  // One instantiation per input shape keeps the inner loops free of the
  // feature and group branches.
  const bool f = !scan.feature.empty(), g = !scan.group.empty();
  if (f) {
    g ? run_impl<true, true>(scan, params, r) : run_impl<true, false>(scan, params, r);
  } else {
    g ? run_impl<false, true>(scan, params, r) : run_impl<false, false>(scan, params, r);
  }
}

// The stages of OrderedScanDbscan::run_impl: cache the trigonometry,
// compact the valid pixels, mark core pixels, build runs of linked core
// pixels, link the runs, number the clusters, label the borders.

[[gnu::always_inline]] inline void OrderedScanDbscan::cache_trig(std::span<const double> angle_rad) {
  // A sensor's pixel angles are the same scan after scan: keep their sines
  // and cosines (they would cost more than the clustering itself).
  const std::size_t n = angle_rad.size();
  if (trig_angle_.size() == n &&
      (n == 0 || std::memcmp(trig_angle_.data(), angle_rad.data(), n * sizeof(double)) == 0)) {
    return;
  }
  trig_angle_.assign(angle_rad.begin(), angle_rad.end());
  sin_.resize(n);
  cos_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    sin_[i] = std::sin(trig_angle_[i]);
    cos_[i] = std::cos(trig_angle_[i]);
  }
}

namespace {

// As pixel_valid(), without the branches an instantiation does not need.
template <bool with_f, bool with_g>
[[gnu::always_inline]] inline bool pixel_valid_as(const OrderedScanPoints& scan, std::size_t i) {
  constexpr double kMax = std::numeric_limits<double>::max();
  const double rr = scan.range_m[i], aa = scan.angle_rad[i];
  bool ok = rr > 0.0 && rr <= kMax && aa >= -kMax && aa <= kMax;
  if constexpr (with_g) ok = ok && scan.group[i] >= 0;
  if constexpr (with_f) ok = ok && std::isfinite(scan.feature[i]);
  return ok;
}

}  // namespace

// One pass over the pixels: compact the valid ones (same coordinates as
// to_points()), check that their bearings are strictly monotone (else a
// reason in r, and 0), compute each block's depth interval (a neighbour also
// satisfies |r_i - r_j| <= eps) and each pixel's squared distance to the
// previous valid one. Returns the number of valid pixels.
template <bool with_f, bool with_g>
[[gnu::always_inline]] inline std::size_t OrderedScanDbscan::compact(const OrderedScanPoints& scan, double eps,
                                                                     DbscanResult& r) {
  constexpr int kBlock = detail::CompactScan<with_f, with_g>::kBlock;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const std::size_t n_all = scan.range_m.size();
  const double eps_wide = eps * (1.0 + 1e-9);
  for (auto* v : {&x_, &z_, &theta_, &range_, &adjacent_}) v->resize(n_all);
  f_.resize(with_f ? n_all : 0);
  g_.resize(with_g ? n_all : 0);
  index_.resize(n_all);
  core_.resize(n_all);
  block_lo_.assign(n_all / kBlock + 1, kInf);
  block_hi_.assign(n_all / kBlock + 1, -kInf);
  std::size_t m = 0;
  double blo = kInf, bhi = -kInf;  // the current block's depth interval (kept in registers)
  double direction = 0.0;          // +1 ascending, -1 descending, 0 unknown yet
  for (std::size_t i = 0; i < n_all; ++i) {
    if (!pixel_valid_as<with_f, with_g>(scan, i)) continue;
    const double ri = scan.range_m[i], ti = scan.angle_rad[i];
    if (m > 0) {
      if (direction == 0.0) direction = ti > theta_[m - 1] ? 1.0 : -1.0;
      if (!(direction * (ti - theta_[m - 1]) > 0.0)) {
        r.status.message = fmt::format(
            "pixel angles must be strictly monotone over valid pixels: pixel {} at {} rad after pixel {} at {} rad", i,
            ti, index_[m - 1], theta_[m - 1]);
        return 0;
      }
    }
    x_[m] = ri * sin_[i];
    z_[m] = ri * cos_[i];
    if constexpr (with_f) f_[m] = scan.feature[i];
    if constexpr (with_g) g_[m] = scan.group[i];
    theta_[m] = ti;
    range_[m] = ri;
    const std::size_t b = m / kBlock;
    if (m % kBlock == 0) blo = kInf, bhi = -kInf;
    blo = std::min(blo, ri - eps_wide);
    bhi = std::max(bhi, ri + eps_wide);
    block_lo_[b] = blo;
    block_hi_[b] = bhi;
    index_[m] = static_cast<int>(i);
    if (m > 0) {  // the squared distance to the previous valid pixel (CompactScan::adjacent)
      double t = x_[m] - x_[m - 1];
      double s2 = t * t;
      t = z_[m] - z_[m - 1];
      s2 += t * t;
      if constexpr (with_f) {
        t = f_[m] - f_[m - 1];
        s2 += t * t;
      }
      if constexpr (with_g) {
        if (g_[m] != g_[m - 1]) s2 = kInf;
      }
      adjacent_[m - 1] = s2;
    }
    ++m;
  }
  if (direction < 0.0) {  // walk a descending scan mirrored
    for (std::size_t k = 0; k < m; ++k) theta_[k] = -theta_[k];
  }
  return m;
}

template <bool with_f, bool with_g>
[[gnu::always_inline]] inline detail::CompactScan<with_f, with_g> OrderedScanDbscan::view(int n, double eps) const {
  return {x_.data(),        z_.data(),        f_.data(),        g_.data(), theta_.data(), range_.data(),
          block_lo_.data(), block_hi_.data(), adjacent_.data(), n,         eps,           eps * eps};
}

namespace {

// Whether pixel i has min_points neighbours (itself included): the adjacent
// pixels first, then walks outwards from there (right, then left), stopping
// as soon as min_points is reached.
template <bool with_f, bool with_g>
[[gnu::always_inline]] inline bool reaches_min_points(const detail::CompactScan<with_f, with_g>& s, int i,
                                                      int min_points) {
  const int n = s.n;
  int count = 1 + (i > 0 && s.adjacent_within(i - 1)) + (i + 1 < n && s.adjacent_within(i));
  if (count >= min_points) return true;
  // The next pixel but one, directly: on a surface it settles the core test
  // (stage 1: 3 + 1). Exact: a pixel outside the bearing window or in a
  // block at another depth is farther than eps anyway. Then the previous
  // pixel but one (the last pixel of a surface).
  count += i + 2 < n && s.d2(i, i + 2) <= s.eps2;
  if (count < min_points) count += i >= 2 && s.d2(i, i - 2) <= s.eps2;
  if (count < min_points) {
    auto counter = [&](int j) {
      count += s.d2(i, j) <= s.eps2;
      return count < min_points;
    };
    if (s.walk_right(i, i + 3, counter)) s.walk_left(i, i - 3, counter);
  }
  return count >= min_points;
}

}  // namespace

template <bool with_f, bool with_g>
[[gnu::always_inline]] inline std::size_t OrderedScanDbscan::mark_core(const detail::CompactScan<with_f, with_g>& s,
                                                                       int min_points, DbscanResult& r) {
  std::size_t num_core = 0;
  for (int i = 0; i < s.n; ++i) {
    const std::uint8_t c = reaches_min_points(s, i, min_points) ? 1 : 0;
    core_[static_cast<std::size_t>(i)] = c;
    r.is_core[static_cast<std::size_t>(index_[static_cast<std::size_t>(i)])] = c;
    num_core += c;
  }
  return num_core;
}

// Consecutive core pixels within eps form runs (a surface is one run),
// joined up front under their last pixel: run_end_[k] is k's run's last
// pixel, run_lo_[k], run_hi_[k] the least and greatest range from k to its
// run's end (at a run's first pixel: the whole run's), parent_ and size_
// the disjoint sets of the runs. The run's end, length and depth interval
// stay in registers (not a load-store chain through run_end_ and size_ per
// pixel).
[[gnu::always_inline]] inline void OrderedScanDbscan::build_runs(int n, double eps2) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (auto* v : {&run_end_, &parent_, &size_}) v->resize(static_cast<std::size_t>(n));
  run_lo_.resize(static_cast<std::size_t>(n));
  run_hi_.resize(static_cast<std::size_t>(n));
  double lo = kInf, hi = -kInf;
  int end = n - 1, length = 0;
  for (int k = n - 1; k >= 0; --k) {
    const auto u = static_cast<std::size_t>(k);
    const bool linked = core_[u] && k + 1 < n && core_[u + 1] && adjacent_[u] <= eps2;
    const double rk = range_[u];
    if (linked) {
      lo = std::min(lo, rk);
      hi = std::max(hi, rk);
    } else {
      if (length > 0) size_[static_cast<std::size_t>(end)] = length;
      end = k;
      length = 0;
      lo = hi = rk;
    }
    ++length;
    run_end_[u] = end;
    run_lo_[u] = lo;
    run_hi_[u] = hi;
    parent_[u] = end;
    size_[u] = 1;
  }
  if (length > 0) size_[static_cast<std::size_t>(end)] = length;
}

// Core-core edges between runs: each core pixel whose bearing window reaches
// past its run looks there for core pixels within eps. Exact shortcuts, per
// run met rather than per pixel: a run already in this run's set, or whose
// depth interval (widened by eps) misses this pixel's range, holds no pair
// that could change the sets; after a union the rest of that run is jumped
// over too.
template <bool with_f, bool with_g>
[[gnu::always_inline]] inline void OrderedScanDbscan::link_runs(const detail::CompactScan<with_f, with_g>& s) {
  const int n = s.n;
  const double eps_wide = s.eps * (1.0 + 1e-9);
  detail::DisjointSets sets(parent_, size_);
  auto core = [&](int i) { return core_[static_cast<std::size_t>(i)] != 0; };
  for (int first = 0; first < n;) {  // run by run
    if (!core(first)) {
      ++first;
      continue;
    }
    const int last = run_end_[static_cast<std::size_t>(first)];
    const int next = last + 1;
    if (next >= n) break;  // the last run: nothing beyond it
    const double next_theta = s.theta[next];
    // Most pixels of a run end their window before the run does. The widest
    // window in the run is its nearest pixel's: pixels before the last one
    // it cannot carry past the run are skipped without a look.
    const double widest = detail::bearing_half_window(s.eps, run_lo_[static_cast<std::size_t>(first)]);
    int start = last;
    while (start > first && s.theta[start - 1] + widest >= next_theta) --start;
    int root = -1;  // this run's set, looked up when first needed
    for (int i = start; i <= last; ++i) {
      const double limit = s.theta[i] + s.half_window(i);
      if (next_theta > limit) continue;
      if (root < 0) root = sets.find(last);
      const double ri = s.range[i];
      for (int j = next; j < n && s.theta[j] <= limit;) {
        if (!core(j)) {
          ++j;
          continue;
        }
        // j starts a run here (the walk enters core pixels only after a
        // non-core one or a run's end): its bounds are the whole run's.
        const int e = run_end_[static_cast<std::size_t>(j)];
        const auto uj = static_cast<std::size_t>(j);
        if (ri < run_lo_[uj] - eps_wide || ri > run_hi_[uj] + eps_wide || sets.find(e) == root) {
          j = e + 1;
          continue;
        }
        for (; j <= e; ++j) {
          if (s.theta[j] > limit) break;
          if (s.d2(i, j) <= s.eps2) {
            sets.unite(i, j);
            root = sets.find(last);
            j = e + 1;
            break;
          }
        }
      }
    }
    first = next;
  }
}

// Clusters in the order of their lowest-indexed core point; a run's pixels
// share a root: one find per run. Returns the number of clusters.
[[gnu::always_inline]] inline int OrderedScanDbscan::number_clusters(int n, DbscanResult& r) {
  detail::DisjointSets sets(parent_, size_);
  cluster_of_root_.assign(static_cast<std::size_t>(n), -1);
  int clusters = 0;
  for (int i = 0; i < n;) {
    if (!core_[static_cast<std::size_t>(i)]) {
      ++i;
      continue;
    }
    const int last = run_end_[static_cast<std::size_t>(i)];
    int& c = cluster_of_root_[static_cast<std::size_t>(sets.find(last))];
    if (c < 0) c = clusters++;
    for (; i <= last; ++i) r.labels[static_cast<std::size_t>(index_[static_cast<std::size_t>(i)])] = c;
  }
  return clusters;
}

// Border points: the lowest-numbered cluster among core points within eps.
// With min_points <= 2 there are none: a point within eps of a core point
// has two neighbours (itself and that one), so it is core itself, and every
// non-core point is noise without a search (stage 3 of the two-stage
// clustering runs with 2). Returns the number of noise points.
template <bool with_f, bool with_g>
[[gnu::always_inline]] inline std::size_t OrderedScanDbscan::label_borders(const detail::CompactScan<with_f, with_g>& s,
                                                                           int min_points, DbscanResult& r) {
  auto core = [&](int i) { return core_[static_cast<std::size_t>(i)] != 0; };
  auto label = [&](int i) -> int& { return r.labels[static_cast<std::size_t>(index_[static_cast<std::size_t>(i)])]; };
  std::size_t num_noise = 0;
  const bool borders_possible = min_points > 2;
  for (int i = 0; i < s.n; ++i) {
    if (core(i)) continue;
    if (!borders_possible) {
      label(i) = kNoise;
      ++num_noise;
      continue;
    }
    int best = kNoise;
    auto consider = [&](int j) {
      if (core(j)) {
        const int lj = label(j);
        if ((best == kNoise || lj < best) && s.d2(i, j) <= s.eps2) best = lj;
      }
      return true;
    };
    s.walk_left(i, i - 1, consider);
    s.walk_right(i, i + 1, consider);
    label(i) = best;
    num_noise += best == kNoise;
  }
  return num_noise;
}

template <bool with_f, bool with_g>
void OrderedScanDbscan::run_impl(const OrderedScanPoints& scan, const DbscanParams& params, DbscanResult& r) {
  const std::size_t n_all = scan.range_m.size();
  r.labels.assign(n_all, kInvalid);
  r.is_core.assign(n_all, 0);
  cache_trig(scan.angle_rad);
  const std::size_t m = compact<with_f, with_g>(scan, params.eps, r);
  if (!r.status.message.empty()) {
    r.labels.clear();
    r.is_core.clear();
    return;
  }
  const int n = static_cast<int>(m);
  const auto s = view<with_f, with_g>(n, params.eps);
  const std::size_t num_core = mark_core(s, params.min_points, r);
  build_runs(n, s.eps2);
  link_runs(s);
  r.num_clusters = number_clusters(n, r);
  const std::size_t num_noise = label_borders(s, params.min_points, r);
  detail::finish(r, num_core, num_noise, n_all - m);
}

DbscanResult dbscan_ordered_scan(const OrderedScanPoints& scan, const DbscanParams& params) {
  OrderedScanDbscan d;
  return d.run(scan, params);
}

}  // namespace tinyline::laser_clustering
