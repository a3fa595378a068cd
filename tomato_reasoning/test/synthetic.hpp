// SPDX-License-Identifier: Apache-2.0
// Synthetic point sets for the tomato core tests: the visible caps of spheres
// as a camera at the origin sees them, with noise, optionally with normals.
#pragma once

#include <random>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/sphere_ransac.hpp"

namespace tinyline::tomato_reasoning::test {

/// Points on the part of the sphere facing `eye` (within `max_angle_deg` of
/// the direction to the eye), Gaussian noise along the radius.
inline void add_cap(std::vector<Eigen::Vector3f>& pts, std::vector<Eigen::Vector3f>* normals, const Sphere& s, int n,
                    double noise_m, std::mt19937& rng, const Eigen::Vector3d& eye = Eigen::Vector3d::Zero(),
                    double max_angle_deg = 70.0) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector3d towards = (eye - s.centre).normalized();
  const double cmin = std::cos(max_angle_deg * M_PI / 180.0);
  int made = 0;
  while (made < n) {
    Eigen::Vector3d d(g(rng), g(rng), g(rng));
    d.normalize();
    if (d.dot(towards) < cmin) continue;
    const Eigen::Vector3d p = s.centre + (s.radius_m + noise_m * g(rng)) * d;
    pts.push_back(p.cast<float>());
    if (normals) normals->push_back(d.cast<float>());
    ++made;
  }
}

}  // namespace tinyline::tomato_reasoning::test
