// Pieces shared by the three DBSCAN neighbour searches (not installed).
#pragma once

#include <cstddef>
#include <cstdint>
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

/// Rejects bad parameters and inputs the same way for every search. Returns
/// an empty string when the call may proceed.
std::string check_points_input(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params);

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
DbscanResult label_from_neighbours(const std::vector<std::uint8_t>& valid, const NeighbourLists& lists,
                                   int min_points);

/// Fills the counters (counted here, or given) and the note of a finished result.
void finish(DbscanResult& r);
void finish(DbscanResult& r, std::size_t num_core, std::size_t num_noise, std::size_t num_invalid);

}  // namespace tinyline::laser_clustering::detail
