// SPDX-License-Identifier: Apache-2.0
// Registers the hydrus_fitting nodes by name (launch files, `tinyline run`).
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::hydrus_fitting {

/// circle_fitter, sequencer. (The simulated Hydrus, hydrus_sim, comes with
/// the simulator's register_nodes().)
void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::hydrus_fitting
