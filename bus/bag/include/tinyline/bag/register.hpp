// SPDX-License-Identifier: Apache-2.0
// Registers the bag nodes for launch files and `tinyline run`:
//   bag/recorder  records topics to an MCAP file (Recorder)
//   bag/player    plays an MCAP file onto the bus (Player)
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::bag {

void register_nodes(bus::NodeRegistry& registry);

}  // namespace tinyline::bag
