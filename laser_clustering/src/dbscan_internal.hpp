// SPDX-License-Identifier: Apache-2.0
// Pieces shared by the three DBSCAN neighbour searches (not installed).
#pragma once

#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <limits>
#include <numbers>
#include <numeric>
#include <utility>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/dbscan.hpp"

namespace tinyline::laser_clustering::detail {

/// Union-find with path halving and union by size, on storage the caller
/// keeps and initialises (parent[i] a root or a member of i's set, size[r]
/// the set size at each root), so a reused OrderedScanDbscan allocates
/// nothing per scan.
class DisjointSets {
 public:
  DisjointSets(std::vector<int>& parent, std::vector<int>& size) : p_(parent), s_(size) {}
  int find(int i) {
    while (p_[i] != i) {
      p_[i] = p_[p_[i]];
      i = p_[i];
    }
    return i;
  }
  /// Joins the sets of a and b; returns false when they already were one.
  bool unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (s_[a] < s_[b]) std::swap(a, b);
    p_[b] = a;
    s_[a] += s_[b];
    return true;
  }

 private:
  std::vector<int>& p_;
  std::vector<int>& s_;
};

/// Squared distance between columns i and j, summed over rows in order (the
/// summation order scikit-learn's tree uses, so ties at eps decide the same way).
inline double squared_distance(const Eigen::Ref<const Eigen::MatrixXd>& p, Eigen::Index i, Eigen::Index j) {
  double s = 0.0;
  for (Eigen::Index k = 0; k < p.rows(); ++k) {
    const double t = p(k, i) - p(k, j);
    s += t * t;
  }
  return s;
}

/// Rejects bad parameters and inputs the same way for every search: ok when
/// the call may proceed.
common::Status check_points_input(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params);

/// Marks columns with a non-finite coordinate invalid; returns the valid count.
std::size_t mark_valid(const Eigen::Ref<const Eigen::MatrixXd>& points, std::vector<std::uint8_t>& valid);

/// Neighbour lists in compressed rows: the neighbours of point i (itself
/// included, valid points only) are nbr[offset[i] .. offset[i+1]).
struct NeighbourLists {
  std::vector<std::size_t> offset;
  std::vector<int> nbr;
};

/// The labelling every search shares: core flags from neighbour counts,
/// clusters as connected components of core points numbered by their lowest
/// index, border points to the lowest-numbered adjacent cluster.
DbscanResult label_from_neighbours(const std::vector<std::uint8_t>& valid, const NeighbourLists& lists, int min_points);

/// Fills the counters (counted here, or given) and the note of a finished result.
void finish(DbscanResult& r);
void finish(DbscanResult& r, std::size_t num_core, std::size_t num_noise, std::size_t num_invalid);

/// Bound on the bearing half-window of a pixel at range range_m: a
/// neighbour within eps satisfies |dtheta| <= asin(eps / r) <= x + (pi/2 - 1)
/// x^3 with x = eps / r (the cubic meets asin at 0 and 1 and stays above it
/// between; it spares an asin per pixel), widened by a hair so rounding never
/// hides a pair at exactly eps. It grows with eps / r, in floating point too
/// (every step rounds monotonically).
[[gnu::always_inline]] inline double bearing_half_window(double eps, double range_m) {
  constexpr double kCubic = std::numbers::pi / 2.0 - 1.0;
  const double x = eps / range_m;
  return x >= 1.0 ? std::numbers::pi * 2.0 : (x + kCubic * x * x * x) * (1.0 + 1e-9) + 1e-12;
}

/// The valid pixels of an ordered scan, compacted in scan order (the
/// buffers of OrderedScanDbscan), with the neighbour tests its stages share.
/// Bearings ascend (a descending scan is mirrored); pixels come in blocks of
/// kBlock whose depth interval, widened by eps, lets a walk skip a block at
/// another depth at once. One instantiation per input shape keeps the inner
/// loops free of the feature and group branches.
template <bool with_feature, bool with_group>
class CompactScan {
 public:
  static constexpr int kBlock = 8;
  static constexpr double kInf = std::numeric_limits<double>::infinity();

  const double* x;         ///< lateral coordinate [m]
  const double* z;         ///< depth coordinate [m]
  const double* f;         ///< feature (with_feature only)
  const int* g;            ///< group id (with_group only)
  const double* theta;     ///< bearing, ascending [rad]
  const double* range;     ///< range [m]
  const double* block_lo;  ///< per block: least range - eps
  const double* block_hi;  ///< per block: greatest range + eps
  const double* adjacent;  ///< adjacent[k]: squared distance of k and k+1
  int n;                   ///< valid pixels
  double eps, eps2;

  [[gnu::always_inline]] [[nodiscard]] double half_window(int i) const { return bearing_half_window(eps, range[i]); }

  /// Squared distance; pixels of different groups are infinitely far apart.
  [[gnu::always_inline]] [[nodiscard]] double d2(int i, int j) const {
    if constexpr (with_group) {
      if (g[i] != g[j]) return kInf;
    }
    double t = x[i] - x[j];
    double s = t * t;
    t = z[i] - z[j];
    s += t * t;
    if constexpr (with_feature) {
      t = f[i] - f[j];
      s += t * t;
    }
    return s;
  }

  /// k and k+1 within eps (adjacent pixels are the likeliest neighbours:
  /// their distances, computed once, serve the core test and the runs).
  [[gnu::always_inline]] [[nodiscard]] bool adjacent_within(int k) const { return adjacent[k] <= eps2; }

  /// Calls visit(j) for j = from, from+1, ... within i's bearing window,
  /// skipping blocks at other depths, until visit returns false. Returns
  /// false if visit stopped it.
  template <class Visit>
  [[gnu::always_inline]] bool walk_right(int i, int from, Visit&& visit) const {
    const double limit = theta[i] + half_window(i), ri = range[i];
    for (int j = from; j < n;) {
      if (theta[j] > limit) return true;
      const auto b = static_cast<std::size_t>(j) / kBlock;  // j >= 0: an unsigned shift
      const int end = std::min(n, static_cast<int>(b + 1) * kBlock);
      if (ri < block_lo[b] || ri > block_hi[b]) {
        j = end;
        continue;
      }
      for (; j < end; ++j) {
        if (theta[j] > limit) return true;
        if (!visit(j)) return false;
      }
    }
    return true;
  }

  /// The same for j = from, from-1, ...
  template <class Visit>
  [[gnu::always_inline]] bool walk_left(int i, int from, Visit&& visit) const {
    const double limit = theta[i] - half_window(i), ri = range[i];
    for (int j = from; j >= 0;) {
      if (theta[j] < limit) return true;
      const auto b = static_cast<std::size_t>(j) / kBlock;
      const int end = static_cast<int>(b * kBlock) - 1;
      if (ri < block_lo[b] || ri > block_hi[b]) {
        j = end;
        continue;
      }
      for (; j > end; --j) {
        if (theta[j] < limit) return true;
        if (!visit(j)) return false;
      }
    }
    return true;
  }
};

}  // namespace tinyline::laser_clustering::detail
