// SPDX-License-Identifier: Apache-2.0
// Inputs shared by the laser_clustering benchmarks: a seeded set of
// 256-pixel pedicel scans (pedicels, tomatoes, a background wall, drag,
// noise) from the unit tests' scan synthesiser, and 3-D point clouds of
// surface patches for the general DBSCAN.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "laser_clustering/line_scan.hpp"
#include "synthetic_scan.hpp"

namespace tinyline::laser_clustering::bench {

inline std::vector<LineScan> pedicel_scans(int count, unsigned seed = 42) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<LineScan> out;
  for (int k = 0; k < count; ++k) {
    std::vector<test::Disc> discs;
    int id = 1;
    const int pedicels = 1 + static_cast<int>(u(rng) * 3);
    for (int p = 0; p < pedicels; ++p) {
      discs.push_back({-0.06 + 0.12 * u(rng), 0.09 + 0.08 * u(rng), 0.0025 + 0.001 * u(rng), 6.0, id++});
    }
    const int tomatoes = static_cast<int>(u(rng) * 3);
    for (int t = 0; t < tomatoes; ++t) {
      discs.push_back({-0.1 + 0.2 * u(rng), 0.18 + 0.1 * u(rng), 0.025 + 0.01 * u(rng), 6.0, id++});
    }
    test::SynthParams sp;
    sp.seed = seed + static_cast<unsigned>(k);
    sp.noise_sd_m = 0.003;
    sp.drag_m = 0.1 * u(rng);
    sp.drag_px = 2;
    if (u(rng) < 0.7) sp.wall_z_m = 0.3 + 0.3 * u(rng);
    out.push_back(test::synth_scan(discs, sp).scan);
  }
  return out;
}

/// n points on random 0.2 m planar patches (a point cloud's structure: dense
/// surfaces, empty space), 2000 points per patch whatever n (constant
/// density: the region grows with n), 1 mm noise; 3 x n.
inline Eigen::MatrixXd surface_cloud(int n, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.001), dir(0.0, 1.0);
  auto random_direction = [&] { return Eigen::Vector3d(dir(rng), dir(rng), dir(rng)).normalized(); };
  const int patches = std::max(1, n / 2000);
  const double side = std::cbrt(patches / 50.0);  // 50 patches per cubic metre
  std::vector<Eigen::Vector3d> origin(patches), e1(patches), e2(patches);
  for (int p = 0; p < patches; ++p) {
    origin[p] = side * Eigen::Vector3d(u(rng), u(rng), u(rng));
    e1[p] = random_direction() * 0.2;
    e2[p] = e1[p].cross(random_direction()).normalized() * 0.2;
  }
  Eigen::MatrixXd cloud(3, n);
  for (int i = 0; i < n; ++i) {
    const int p = static_cast<int>(u(rng) * patches);
    cloud.col(i) = origin[p] + u(rng) * e1[p] + u(rng) * e2[p] + Eigen::Vector3d(g(rng), g(rng), g(rng));
  }
  return cloud;
}

}  // namespace tinyline::laser_clustering::bench
