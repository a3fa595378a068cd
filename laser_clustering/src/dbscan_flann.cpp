// SPDX-License-Identifier: Apache-2.0
// The general-point-set DBSCAN on FLANN's exact single kd-tree. FLANN's
// headers are heavy, so they stay in this one file.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <flann/algorithms/dist.h>
#include <flann/algorithms/kdtree_single_index.h>
#include <flann/util/matrix.h>
#include <flann/util/params.h>
#include <flann/util/result_set.h>

#include "dbscan_internal.hpp"
#include "laser_clustering/dbscan.hpp"

namespace tinyline::laser_clustering {

namespace {

/// A FLANN result set that appends every point within eps (exactly) to a
/// neighbour list, with no per-query allocation.
class CsrResultSet : public flann::ResultSet<double> {
 public:
  CsrResultSet(std::vector<int>& out, double eps2, double search_radius2)
      : out_(out), eps2_(eps2), search_radius2_(search_radius2) {}
  bool full() const override { return true; }
  void addPoint(double dist, size_t index) override {
    if (dist <= eps2_) out_.push_back(static_cast<int>(index));
  }
  double worstDist() const override { return search_radius2_; }

 private:
  std::vector<int>& out_;
  double eps2_, search_radius2_;
};

}  // namespace

DbscanResult dbscan(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  DbscanResult bad;
  if (bad.status = detail::check_points_input(points, params); !bad.status.ok()) return bad;
  std::vector<std::uint8_t> valid;
  const std::size_t n_valid = detail::mark_valid(points, valid);
  const auto n = static_cast<std::size_t>(points.cols());
  const auto dim = static_cast<std::size_t>(points.rows());

  detail::NeighbourLists lists;
  lists.offset.assign(n + 1, 0);
  if (n_valid == 0) return detail::label_from_neighbours(valid, lists, params.min_points);

  // FLANN wants the valid points row-major and contiguous.
  std::vector<double> data(n_valid * dim);
  std::vector<int> original(n_valid);
  for (std::size_t i = 0, k = 0; i < n; ++i) {
    if (!valid[i]) continue;
    for (std::size_t d = 0; d < dim; ++d) {
      data[k * dim + d] = points(static_cast<Eigen::Index>(d), static_cast<Eigen::Index>(i));
    }
    original[k++] = static_cast<int>(i);
  }
  const flann::Matrix<double> dataset(data.data(), n_valid, dim);
  // L2_Simple sums squared differences in coordinate order, as we do.
  flann::KDTreeSingleIndex<flann::L2_Simple<double>> index(dataset, flann::KDTreeSingleIndexParams(10, false));
  index.buildIndex();

  // Neighbours go straight into the compressed rows. FLANN keeps a point
  // when its distance is < worstDist() and prunes boxes against it; boxes'
  // distances are accumulated incrementally and may round up, so worstDist()
  // is a little more than eps^2, and membership is decided here exactly:
  // FLANN's L2_Simple sums squared differences in coordinate order, the
  // very number our rule compares (|p - q|^2 <= eps^2).
  const double eps2 = params.eps * params.eps;
  CsrResultSet result(lists.nbr, eps2, eps2 * (1.0 + 1e-9) + 1e-300);
  const flann::SearchParams search(flann::FLANN_CHECKS_UNLIMITED, 0.0f, false);
  std::size_t next_row = 0;  // rows are written in index order; invalid points get empty rows
  for (std::size_t q = 0; q < n_valid; ++q) {
    const auto i = static_cast<std::size_t>(original[q]);
    for (; next_row <= i; ++next_row) lists.offset[next_row] = lists.nbr.size();
    const std::size_t row_begin = lists.nbr.size();
    index.findNeighbors(result, data.data() + q * dim, search);
    // FLANN reports positions among the valid points: map back to input indices.
    for (std::size_t k = row_begin; k < lists.nbr.size(); ++k) {
      lists.nbr[k] = original[static_cast<std::size_t>(lists.nbr[k])];
    }
  }
  for (; next_row <= n; ++next_row) lists.offset[next_row] = lists.nbr.size();
  return detail::label_from_neighbours(valid, lists, params.min_points);
}

}  // namespace tinyline::laser_clustering
