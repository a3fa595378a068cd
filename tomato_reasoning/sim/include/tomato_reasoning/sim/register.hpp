// SPDX-License-Identifier: Apache-2.0
// tomato_reasoning's simulated nodes (built with the simulator and the
// tomato evaluation).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::tomato_reasoning {

/// Registers the harvest demo's simulated nodes: tomato_reasoning/truss_camera,
/// sim_gripper and harvest_score. The `tinyline` tool calls it beside
/// register_nodes().
void register_sim_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::tomato_reasoning
