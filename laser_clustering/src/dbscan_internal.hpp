// Pieces shared by the three DBSCAN neighbour searches (not installed).
#pragma once

#include <cstddef>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/dbscan.hpp"

namespace tinyline::laser_clustering::detail {

/// Union-find with path halving and union by index (the smaller root wins, so
/// a root is its component's lowest index; not needed for correctness, but it
/// keeps trees shallow for scans processed right to left).
class DisjointSets {
 public:
  void reset(std::vector<int>& storage, std::size_t n) {
    p_ = &storage;
    storage.resize(n);
    std::iota(storage.begin(), storage.end(), 0);
  }
  int find(int i) {
    auto& p = *p_;
    while (p[i] != i) {
      p[i] = p[p[i]];
      i = p[i];
    }
    return i;
  }
  /// Joins the sets of a and b; returns false when they already were one.
  bool unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (a < b) {
      (*p_)[b] = a;
    } else {
      (*p_)[a] = b;
    }
    return true;
  }

 private:
  std::vector<int>* p_ = nullptr;
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

/// Fills the counters and the note of a finished result.
void finish(DbscanResult& r);

}  // namespace tinyline::laser_clustering::detail
