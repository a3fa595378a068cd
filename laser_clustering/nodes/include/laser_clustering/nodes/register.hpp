// SPDX-License-Identifier: Apache-2.0
// Registers the laser_clustering nodes by name (launch files, `tinyline run`).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::laser_clustering {

/// line_clusterer, pedicel_finder, tomato_registration, reflectance_clusterer,
/// alignment_search, pitch_sweep. (The simulated gripper, sim_gripper_pitch,
/// comes with the simulator's register_nodes().)
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::laser_clustering
