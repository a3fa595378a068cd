// SPDX-License-Identifier: Apache-2.0
// Registers the driver's node types (tiny_laser_driver/laser_driver).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::tiny_laser_driver {

void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::tiny_laser_driver
