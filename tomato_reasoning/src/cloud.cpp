#include "tomato_reasoning/cloud.hpp"

namespace tinyline::tomato_reasoning {

std::string check_cloud(const ColorCloud& c) {
  if (c.xyz.size() != c.rgb.size())
    return "cloud has " + std::to_string(c.xyz.size()) + " points but " + std::to_string(c.rgb.size()) + " colours";
  if (c.width < 0 || c.height < 1) return "cloud has width " + std::to_string(c.width) + ", height " + std::to_string(c.height);
  if (static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height) != c.xyz.size())
    return "cloud is " + std::to_string(c.width) + " x " + std::to_string(c.height) + " but holds " +
           std::to_string(c.xyz.size()) + " points";
  return {};
}

}  // namespace tinyline::tomato_reasoning
