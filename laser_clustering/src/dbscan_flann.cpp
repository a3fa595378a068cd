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

#include "dbscan_internal.hpp"
#include "laser_clustering/dbscan.hpp"

namespace tinyline::laser_clustering {

DbscanResult dbscan(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  DbscanResult bad;
  if (bad.reason = detail::check_points_input(points, params); !bad.reason.empty()) return bad;
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

  // FLANN takes the radius as a float and keeps dist < radius: search a
  // slightly larger ball, then decide membership with our exact rule.
  const double eps2 = params.eps * params.eps;
  const auto search_radius = static_cast<float>(eps2 * (1.0 + 1e-5) + 1e-300);
  flann::SearchParams search;
  search.eps = 0.0f;
  search.sorted = false;
  search.max_neighbors = -1;

  std::vector<std::vector<std::size_t>> found;
  std::vector<std::vector<double>> dists;
  std::size_t next_row = 0;  // rows are written in index order; invalid points get empty rows
  constexpr std::size_t kBatch = 4096;  // bounds the memory of the candidate lists
  for (std::size_t first = 0; first < n_valid; first += kBatch) {
    const std::size_t count = std::min(kBatch, n_valid - first);
    const flann::Matrix<double> queries(data.data() + first * dim, count, dim);
    index.radiusSearch(queries, found, dists, search_radius, search);
    for (std::size_t q = 0; q < count; ++q) {
      const auto i = static_cast<std::size_t>(original[first + q]);
      for (; next_row <= i; ++next_row) lists.offset[next_row] = lists.nbr.size();
      for (const std::size_t c : found[q]) {
        const auto j = static_cast<Eigen::Index>(original[c]);
        if (detail::squared_distance(points, static_cast<Eigen::Index>(i), j) <= eps2) {
          lists.nbr.push_back(static_cast<int>(j));
        }
      }
    }
  }
  for (; next_row <= n; ++next_row) lists.offset[next_row] = lists.nbr.size();
  return detail::label_from_neighbours(valid, lists, params.min_points);
}

}  // namespace tinyline::laser_clustering
