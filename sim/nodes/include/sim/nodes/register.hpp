// SPDX-License-Identifier: Apache-2.0
// Every simulator-backed node type by name, for launch files and `tinyline
// run`, and the driver's `sim:SCENE.yaml` port scheme.
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::sim {

/// Registers sim/virtual_sensor and sim/scene_truth; laser_clustering/
/// sim_gripper_pitch (a generic pitch joint, named for the launch files that
/// use it); and the driver's `sim:` port scheme (sim/nodes/port.hpp). The
/// applications' simulated nodes register from their own packages
/// (`<pkg>/sim/register.hpp`). The `tinyline` tool calls it with every
/// package's register_nodes().
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::sim
