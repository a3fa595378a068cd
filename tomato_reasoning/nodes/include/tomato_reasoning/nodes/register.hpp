// Registers the tomato_reasoning nodes by name (launch files, `tinyline run`).
#pragma once

#include <functional>

#include <tinyline/bus/registry.hpp>

namespace tinyline::tomato_reasoning {

/// tomato_detector, pick_verifier; and, in a build with the simulator, the
/// demo's truss_camera and hand_laser (registered through add_extra_nodes).
void register_nodes(bus::NodeRegistry& registry);

/// For node libraries that are not installed (the simulator-backed demo
/// nodes): register_nodes() also calls every function added here.
bool add_extra_nodes(std::function<void(bus::NodeRegistry&)> registrar);

}  // namespace tinyline::tomato_reasoning
