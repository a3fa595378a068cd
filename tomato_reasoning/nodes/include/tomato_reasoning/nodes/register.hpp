// SPDX-License-Identifier: Apache-2.0
// Registers the tomato_reasoning nodes by name (launch files, `tinyline run`).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::tomato_reasoning {

/// tomato_detector, pick_verifier, rgbd_folder_camera. (The demo's simulated truss_camera,
/// sim_gripper and harvest_score come with the simulator's register_nodes().)
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::tomato_reasoning
