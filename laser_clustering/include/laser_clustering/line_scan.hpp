// One calibrated scan of the tiny TOF line sensor as the cores see it: plain
// vectors in pixel order, no message types (a node fills it from a
// tinyline_msgs/LineScan).
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace tinyline::laser_clustering {

/// Pixel i looks along angle_rad[i] in the sensor's x-z plane (z forward
/// along the optical axis, x along the line; the point is
/// (range sin(angle), range cos(angle))). Angles must be strictly monotone.
struct LineScan {
  std::vector<double> angle_rad;
  /// Range along the ray [m]; NaN (or anything not finite and > 0) marks an invalid pixel.
  std::vector<double> range_m;
  /// The driver's reflectance figure (distance_cm^2 (a+b) / (pulses/10)) per
  /// pixel; empty when the scan carries none.
  std::vector<double> reflectance;

  [[nodiscard]] std::size_t size() const { return range_m.size(); }
  [[nodiscard]] bool valid(std::size_t i) const {
    // Written so that NaN fails every comparison.
    return i < range_m.size() && range_m[i] > 0.0 && range_m[i] <= std::numeric_limits<double>::max();
  }
  [[nodiscard]] std::size_t num_valid() const;
  /// Median spacing of adjacent pixel bearings [rad] (the footprint of one
  /// pixel is this times the range); NaN with fewer than two angles.
  [[nodiscard]] double pixel_pitch_rad() const;
};

/// Empty when the scan is well formed, else what is wrong: mismatched
/// lengths, non-finite angles, or angles that are not strictly monotone.
[[nodiscard]] std::string check_scan(const LineScan& scan);

}  // namespace tinyline::laser_clustering
