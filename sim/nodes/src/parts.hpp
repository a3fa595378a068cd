// SPDX-License-Identifier: Apache-2.0
// The parts of the simulator's node library, each registering its node types
// (and the port scheme) by name; register_nodes() (register.cpp) calls them all.
#pragma once

#include <tinyline/bus/params.hpp>
#include <tinyline/bus/registry.hpp>

#include <sim/nodes/nodes.hpp>

namespace tinyline::sim::nodes {

/// sim/virtual_sensor, sim/scene_truth (always).
void register_scene_nodes(bus::NodeRegistry& registry);
/// laser_clustering/sim_gripper_pitch (always).
void register_gripper_nodes(bus::NodeRegistry& registry);
/// The driver's `sim:` port scheme.
void register_port(bus::NodeRegistry& registry);

}  // namespace tinyline::sim::nodes
