// SPDX-License-Identifier: Apache-2.0
// The PointCloud2 field layout the project's colour clouds use.
#pragma once

#include <cstdint>

#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>

namespace tinyline::msg {

/// Sets `c`'s fields to x, y, z and rgb, each one float32 at offsets 0, 4,
/// 8 and 12 (PCL's PointXYZRGB packing; the point step is the caller's).
inline void set_xyzrgb_fields(sensor_msgs::msg::PointCloud2& c) {
  c.fields.clear();
  const char* names[] = {"x", "y", "z", "rgb"};
  for (std::uint32_t k = 0; k < 4; ++k) {
    sensor_msgs::msg::PointField f;
    f.name = names[k];
    f.offset = 4 * k;
    f.datatype = sensor_msgs::msg::PointField::FLOAT32;
    f.count = 1;
    c.fields.push_back(f);
  }
}

}  // namespace tinyline::msg
