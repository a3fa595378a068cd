// SPDX-License-Identifier: Apache-2.0
// hydrus_fitting's simulated nodes (built with the simulator).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::hydrus_fitting {

/// Registers hydrus_fitting/hydrus_sim (the simulated Hydrus flying the
/// grasp). The `tinyline` tool calls it beside register_nodes().
void register_sim_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::hydrus_fitting
