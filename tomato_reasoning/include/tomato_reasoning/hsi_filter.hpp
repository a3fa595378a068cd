// SPDX-License-Identifier: Apache-2.0
// HSI colour filter (thesis 4.3.1): the candidate points of ripe tomatoes.
//
// Hue, saturation and intensity are those of PCL's PackedHSIComparison (the
// filter the thesis's jsk_pcl_ros pipeline used), from 8-bit r, g, b:
//   hue        atan2((g - b) * 111/255, (2r - g - b) / 4)        (red = 0 deg)
//   intensity  I = floor((r + g + b) / 3)                        [0, 255]
//   saturation S = 255 - floor(min(r, g, b) * 255 / I)           [0, 255]
// and the thesis's ranges -15 <= H <= 15 deg, 100 <= S <= 250,
// 25 <= I <= 180 (the thesis's HSI filter) are the defaults. The
// hue test is done without atan2 (a point's hue lies within the range
// exactly when its (hx, hy) vector lies inside the range's wedge).
#pragma once

#include <string>

#include "tomato_reasoning/cloud.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct HsiFilterParams {
  double h_min_deg = -15.0;  ///< hue range [deg], within [-180, 180]
  double h_max_deg = 15.0;
  int s_min = 100;  ///< saturation range [0, 255]
  int s_max = 250;
  int i_min = 25;  ///< intensity range [0, 255]
  int i_max = 180;
};

/// Empty when usable, else why not.
common::Status validate(const HsiFilterParams& p);

struct Hsi {
  double h_deg = 0.0;
  int s = 0;
  int i = 0;
};
/// PCL's definition, hue in degrees (not quantised to PCL's int8).
[[nodiscard]] Hsi to_hsi(const Rgb& c);

/// Precomputed test for one parameter set.
class HsiFilter {
 public:
  /// Throws std::invalid_argument with the reason on bad parameters.
  explicit HsiFilter(const HsiFilterParams& params = {});
  [[nodiscard]] bool passes(const Rgb& c) const;
  [[nodiscard]] const HsiFilterParams& params() const { return params_; }

 private:
  HsiFilterParams params_;
  double cos_min_, sin_min_, cos_max_, sin_max_;
  bool wide_;  // the hue range spans more than 180 deg
};

struct HsiFilterResult {
  Indices indices;         ///< finite points that pass, in cloud order
  std::size_t finite = 0;  ///< finite points looked at
  /// Not ok when `indices` is empty: InvalidArgument for bad parameters or a
  /// malformed cloud, NotFound for an empty cloud, no depth or no red point.
  common::Status status;
};

/// Over a ColorCloud or any CloudView (a PCL cloud: pcl_conversions.hpp).
[[nodiscard]] HsiFilterResult filter_hsi(const CloudView& cloud, const HsiFilterParams& params = {});

}  // namespace tinyline::tomato_reasoning
