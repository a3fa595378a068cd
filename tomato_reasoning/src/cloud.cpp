// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/cloud.hpp"

namespace tinyline::tomato_reasoning {

common::Status check_cloud(const ColorCloud& c) {
  if (c.xyz.size() != c.rgb.size())
    return common::Status::invalid("cloud has " + std::to_string(c.xyz.size()) + " points but " +
                                   std::to_string(c.rgb.size()) + " colours");
  if (c.width < 0 || c.height < 1)
    return common::Status::invalid("cloud has width " + std::to_string(c.width) + ", height " +
                                   std::to_string(c.height));
  if (static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height) != c.xyz.size())
    return common::Status::invalid("cloud is " + std::to_string(c.width) + " x " + std::to_string(c.height) +
                                   " but holds " + std::to_string(c.xyz.size()) + " points");
  return {};
}

CloudView::CloudView(const ColorCloud& c) : problem(check_cloud(c).message) {
  if (!problem.empty() || c.empty()) return;
  width = c.width;
  height = c.height;
  xyz = reinterpret_cast<const std::uint8_t*>(c.xyz.data());  // NOLINT: Vector3f is three packed floats
  xyz_stride = sizeof(Eigen::Vector3f);
  r = &c.rgb[0][0];
  g = &c.rgb[0][1];
  b = &c.rgb[0][2];
  rgb_stride = sizeof(Rgb);
}

common::Status check_view(const CloudView& v) {
  if (!v.problem.empty()) return common::Status::invalid(v.problem);
  if (v.width < 0 || v.height < 1)
    return common::Status::invalid("cloud has width " + std::to_string(v.width) + ", height " +
                                   std::to_string(v.height));
  if (v.empty()) return {};
  if (!v.xyz || !v.r || !v.g || !v.b)
    return common::Status::invalid("cloud of " + std::to_string(v.size()) + " points has no point data");
  if (v.xyz_stride < 3 * sizeof(float) && v.size() > 1)
    return common::Status::invalid("point stride " + std::to_string(v.xyz_stride) + " bytes is shorter than x, y, z");
  if (v.rgb_stride < 1 && v.size() > 1) return common::Status::invalid("colour stride is 0");
  return {};
}

}  // namespace tinyline::tomato_reasoning
