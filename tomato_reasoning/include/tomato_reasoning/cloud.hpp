// The coloured point cloud the tomato cores work on: an RGB-D camera's
// organised XYZRGB frame (or any unorganised set of coloured points) as
// plain vectors, so that a core signature needs neither PCL nor a message.
// Code that holds PCL clouds converts to it at its own boundary.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

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

/// Empty when the cloud is well formed, else what is wrong (xyz and rgb of
/// different lengths, width * height not the size).
[[nodiscard]] std::string check_cloud(const ColorCloud& cloud);

/// Indices of points into a cloud.
using Indices = std::vector<int>;

}  // namespace tinyline::tomato_reasoning
