// SPDX-License-Identifier: Apache-2.0
// PCL clouds in and out of the tomato cores. `view_of` lets the pipeline
// read a pcl::PointCloud of XYZRGB-like points (PointXYZRGB, PointXYZRGBA,
// PointXYZRGBNormal: organised or not, NaN where no depth) in place; the
// copies are for code that wants to own a ColorCloud or hand a PCL cloud on.
// Header-only, so the core library itself never compiles against PCL's
// headers: include it where the PCL clouds already are.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "tomato_reasoning/cloud.hpp"

namespace tinyline::tomato_reasoning {

/// A view of `cloud`'s points, no copy: valid while `cloud` lives and is not
/// resized. PointT has float x, y, z (consecutive, as PCL lays them out) and
/// 8-bit r, g, b.
template <typename PointT>
[[nodiscard]] CloudView view_of(const pcl::PointCloud<PointT>& cloud) {
  CloudView v;
  const std::size_t n = cloud.points.size();
  if (static_cast<std::size_t>(cloud.width) * cloud.height != n) {
    v.problem = "PCL cloud is " + std::to_string(cloud.width) + " x " + std::to_string(cloud.height) + " but holds " +
                std::to_string(n) + " points";
    return v;
  }
  if (n == 0) return v;
  const PointT& p0 = cloud.points.front();
  v.width = static_cast<int>(cloud.width);
  v.height = static_cast<int>(cloud.height);
  v.xyz = reinterpret_cast<const std::uint8_t*>(&p0.x);  // NOLINT: x, y, z are consecutive floats in PCL points
  v.xyz_stride = sizeof(PointT);
  v.r = &p0.r;
  v.g = &p0.g;
  v.b = &p0.b;
  v.rgb_stride = sizeof(PointT);
  return v;
}

/// An owned copy (same width, height and order; NaN points kept).
template <typename PointT>
[[nodiscard]] ColorCloud to_color_cloud(const pcl::PointCloud<PointT>& cloud) {
  ColorCloud c;
  c.xyz.reserve(cloud.points.size());
  c.rgb.reserve(cloud.points.size());
  for (const PointT& p : cloud.points) {
    c.xyz.emplace_back(p.x, p.y, p.z);
    c.rgb.push_back(Rgb{p.r, p.g, p.b});
  }
  c.width = static_cast<int>(cloud.width);
  c.height = static_cast<int>(cloud.height);
  return c;
}

/// A PCL copy of a ColorCloud (organised stays organised; is_dense when every
/// point has depth).
[[nodiscard]] inline pcl::PointCloud<pcl::PointXYZRGB> to_pcl(const ColorCloud& c) {
  pcl::PointCloud<pcl::PointXYZRGB> out;
  out.points.resize(c.size());
  bool dense = true;
  for (std::size_t k = 0; k < c.size(); ++k) {
    pcl::PointXYZRGB& p = out.points[k];
    p.x = c.xyz[k].x();
    p.y = c.xyz[k].y();
    p.z = c.xyz[k].z();
    p.r = c.rgb[k][0];
    p.g = c.rgb[k][1];
    p.b = c.rgb[k][2];
    dense = dense && c.finite(k);
  }
  out.width = static_cast<std::uint32_t>(c.width);
  out.height = static_cast<std::uint32_t>(c.height);
  out.is_dense = dense;
  return out;
}

}  // namespace tinyline::tomato_reasoning
