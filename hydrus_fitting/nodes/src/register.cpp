#include "hydrus_fitting/nodes/register.hpp"

#include "hydrus_fitting/nodes/circle_fitter_node.hpp"

namespace tinyline::hydrus_fitting {

void register_nodes(bus::NodeRegistry& r) {
  r.add<CircleFitterNode>("hydrus_fitting", "circle_fitter",
                          "fuses every sensor's scans at their joint angles, filters the robot out, fits a circle");
}

}  // namespace tinyline::hydrus_fitting
