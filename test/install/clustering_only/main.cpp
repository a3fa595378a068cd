// SPDX-License-Identifier: Apache-2.0
// Clusters two groups of points on a line with the installed DBSCAN.
#include <cstdio>

#include <laser_clustering/dbscan.hpp>

int main() {
  Eigen::MatrixXd points(1, 7);
  points << 0.0, 0.1, 0.2, 5.0, 5.1, 5.2, 9.0;
  const auto r = tinyline::laser_clustering::dbscan(points, {.eps = 0.15, .min_points = 2});
  if (!r.status.ok() || r.num_clusters != 2 || r.num_noise != 1) {
    return std::printf("clustering_only: %d clusters, %zu noise (%s)\n", r.num_clusters, r.num_noise,
                       r.status.message.c_str()),
           1;
  }
  std::puts("clustering_only: ok");
  return 0;
}
