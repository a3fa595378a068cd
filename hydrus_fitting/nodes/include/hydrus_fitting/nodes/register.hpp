// Registers the hydrus_fitting nodes by name (launch files, `tinyline run`).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::hydrus_fitting {

/// circle_fitter, sequencer, and hydrus_sim when built with the simulator.
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::hydrus_fitting
