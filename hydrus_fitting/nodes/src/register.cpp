// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/nodes/register.hpp"

#include "hydrus_fitting/nodes/circle_fitter_node.hpp"
#include "hydrus_fitting/nodes/sequencer_node.hpp"

namespace tinyline::hydrus_fitting {

void register_nodes(bus::NodeRegistry& r) {
  r.add<CircleFitterNode>("hydrus_fitting", "circle_fitter",
                          "fuses every sensor's scans at their joint angles, filters the robot out, fits a circle");
  r.add<SequencerNode>("hydrus_fitting", "sequencer",
                       "switches the sensors' lasers so that no two whose views overlap emit at once (Algorithm 4)");
}

}  // namespace tinyline::hydrus_fitting
