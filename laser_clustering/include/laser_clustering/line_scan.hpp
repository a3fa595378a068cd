// SPDX-License-Identifier: Apache-2.0
// One calibrated scan of the tiny TOF line sensor as the cores see it: plain
// vectors in pixel order, no message types (a node fills it from a
// tinyline_msgs/LineScan).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <tinyline/common/status.hpp>

namespace tinyline::laser_clustering {

/// Pixel i looks along angle_rad[i] in the sensor's x-z plane (z forward
/// along the optical axis, x along the line; the point is
/// (range sin(angle), range cos(angle))). Angles must be strictly monotone.
struct LineScan {
  std::vector<double> angle_rad;
  /// Range along the ray [m]; NaN (or anything not finite and > 0) marks an invalid pixel.
  std::vector<double> range_m;
  /// The driver's reflectance figure (distance_cm^2 (a+b) / (pulses/10)) per
  /// pixel; empty when the scan carries none. On an invalid pixel a finite
  /// value is a lower bound: a saturated pixel (see saturated_reflectance_bound).
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

/// A saturated pixel has no distance, and its light is a lower bound (the
/// fewest-pulse read-out's charges, clipped): the brightest returns, a
/// metal's specular peak, are exactly the ones that saturate. This gives
/// such a pixel the reflectance figure of that light at the range of the
/// nearest valid pixel within max_gap_px (same surface, about the same
/// range), as a lower bound of its reflectance: reflectance[i] =
/// (100 range)^2 * intensity[i] * 10, intensity in charge_unit per pulse.
/// Pixels that are not saturated, or without a valid neighbour that near,
/// keep their value. Returns how many pixels got a bound. `saturated` and
/// `intensity` have the scan's size (else nothing is done and 0 returned).
std::size_t saturated_reflectance_bound(LineScan& scan, const std::vector<std::uint8_t>& saturated,
                                        const std::vector<double>& intensity, int max_gap_px = 4);

/// Ok when the scan is well formed, else InvalidArgument saying what is
/// wrong: mismatched lengths, non-finite angles, or angles that are not
/// strictly monotone.
[[nodiscard]] common::Status check_scan(const LineScan& scan);

}  // namespace tinyline::laser_clustering
