// SPDX-License-Identifier: Apache-2.0
// The parts of the simulator's node library, each registering its node types
// (and the port scheme) by name. Which parts a build has depends on the
// packages in it; sim/CMakeLists.txt generates register_nodes() from the
// parts it compiles.
#pragma once

#include <tinyline/bus/params.hpp>
#include <tinyline/bus/registry.hpp>

#include <sim/yaml_node.hpp>

namespace tinyline::sim::nodes {

/// The constraints of a node's `scene` parameter: an input file, checked when
/// the node is built, so a launch (and `launch --check`) stops at the line
/// that set it.
inline bus::ParamConstraints scene_file() { return bus::ParamConstraints::input_file(kMaxConfigFileBytes); }

/// sim/virtual_sensor, sim/scene_truth (always).
void register_scene_nodes(bus::NodeRegistry& registry);
/// laser_clustering/sim_gripper_pitch (always).
void register_gripper_nodes(bus::NodeRegistry& registry);
/// The driver's `sim:` port scheme (with tiny_laser_driver).
void register_port(bus::NodeRegistry& registry);
/// hydrus_fitting/hydrus_sim (with hydrus_fitting).
void register_hydrus_nodes(bus::NodeRegistry& registry);
/// tomato_reasoning/truss_camera, and with it register_harvest_nodes() (with
/// tomato_reasoning's evaluation, which needs laser_clustering and the driver).
void register_truss_nodes(bus::NodeRegistry& registry);
/// tomato_reasoning/sim_gripper, tomato_reasoning/harvest_score.
void register_harvest_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::sim::nodes
