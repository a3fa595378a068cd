// SPDX-License-Identifier: Apache-2.0
#include <sim/nodes/register.hpp>

#include "parts.hpp"

namespace tinyline::sim {

void register_nodes(bus::NodeRegistry& registry) {
  nodes::register_scene_nodes(registry);
  nodes::register_gripper_nodes(registry);
  nodes::register_port(registry);
}

}  // namespace tinyline::sim
