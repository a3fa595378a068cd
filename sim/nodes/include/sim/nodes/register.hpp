// The simulator's nodes, by name, for launch files and `tinyline run`.
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::sim {

/// Registers sim/virtual_sensor and sim/scene_truth.
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::sim
