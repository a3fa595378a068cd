// Registers the laser_clustering nodes by name (launch files, `tinyline run`).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::laser_clustering {

/// line_clusterer, pedicel_finder, reflectance_clusterer, alignment_search,
/// pitch_sweep; sim_gripper_pitch when built with the simulator.
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::laser_clustering
