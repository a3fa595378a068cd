// SPDX-License-Identifier: Apache-2.0
// The coloured point cloud the tomato cores work on: an RGB-D camera's
// organised XYZRGB frame (or any unorganised set of coloured points) as
// plain vectors, so that a core signature needs neither PCL nor a message.
// The pipeline reads its input through a CloudView: a non-owning, strided
// view that fits both a ColorCloud and a pcl::PointCloud<pcl::PointXYZRGB>
// (see pcl_conversions.hpp), so a PCL cloud is read in place, not copied.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

using Rgb = std::array<std::uint8_t, 3>;

struct ColorCloud {
  /// Organised clouds: width x height pixels, row-major; unorganised:
  /// height 1 and width = size.
  int width = 0;
  int height = 1;
  /// Points in the camera's frame [m]; a non-finite coordinate marks a pixel
  /// without depth.
  std::vector<Eigen::Vector3f> xyz;
  std::vector<Rgb> rgb;  ///< 8-bit sRGB colour of each point

  [[nodiscard]] std::size_t size() const { return xyz.size(); }
  [[nodiscard]] bool empty() const { return xyz.empty(); }
  [[nodiscard]] bool organised() const { return height > 1; }
  [[nodiscard]] bool finite(std::size_t i) const { return xyz[i].allFinite(); }
  void push_back(const Eigen::Vector3f& p, const Rgb& c) {
    xyz.push_back(p);
    rgb.push_back(c);
    width = static_cast<int>(xyz.size());
    height = 1;
  }
};

/// A read-only view of width x height coloured points laid out with a fixed
/// stride: x, y, z as three consecutive floats at `xyz + k * xyz_stride`
/// bytes, and 8-bit r, g, b at `r/g/b + k * rgb_stride` bytes. It borrows:
/// the viewed points must outlive it.
struct CloudView {
  int width = 0;
  int height = 1;
  const std::uint8_t* xyz = nullptr;
  std::size_t xyz_stride = 0;
  const std::uint8_t* r = nullptr;
  const std::uint8_t* g = nullptr;
  const std::uint8_t* b = nullptr;
  std::size_t rgb_stride = 0;
  /// Set when the viewed ColorCloud is malformed (what check_cloud says);
  /// such a view is empty.
  std::string problem;

  CloudView() = default;
  // Implicit on purpose: every entry point taking a view takes a ColorCloud.
  CloudView(const ColorCloud& c);  // NOLINT(google-explicit-constructor)

  [[nodiscard]] std::size_t size() const {
    return static_cast<std::size_t>(width < 0 ? 0 : width) * static_cast<std::size_t>(height < 0 ? 0 : height);
  }
  [[nodiscard]] bool empty() const { return size() == 0; }
  [[nodiscard]] bool organised() const { return height > 1; }
  [[nodiscard]] Eigen::Vector3f point(std::size_t k) const {
    const auto* f = reinterpret_cast<const float*>(xyz + k * xyz_stride);  // NOLINT: the layout is the caller's promise
    return {f[0], f[1], f[2]};
  }
  [[nodiscard]] Rgb colour(std::size_t k) const {
    const std::size_t o = k * rgb_stride;
    return {r[o], g[o], b[o]};
  }
  [[nodiscard]] bool finite(std::size_t k) const { return point(k).allFinite(); }
};

/// Whether the view can be read (well formed, points present where it has a size, a
/// stride at least as large as the data it steps over): InvalidArgument says what is wrong.
[[nodiscard]] common::Status check_view(const CloudView& view);

/// Whether the cloud is well formed: InvalidArgument says what is wrong (xyz
/// and rgb of different lengths, width * height not the size).
[[nodiscard]] common::Status check_cloud(const ColorCloud& cloud);

/// Indices of points into a cloud.
using Indices = std::vector<int>;

}  // namespace tinyline::tomato_reasoning
