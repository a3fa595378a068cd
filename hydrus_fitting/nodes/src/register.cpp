#include "hydrus_fitting/nodes/register.hpp"

#include "hydrus_fitting/nodes/circle_fitter_node.hpp"
#include "hydrus_fitting/nodes/sequencer_node.hpp"
#if TINYLINE_HYDRUS_WITH_SIM
#include "hydrus_fitting/nodes/hydrus_sim_node.hpp"
#endif

namespace tinyline::hydrus_fitting {

void register_nodes(bus::NodeRegistry& r) {
  r.add<CircleFitterNode>("hydrus_fitting", "circle_fitter",
                          "fuses every sensor's scans at their joint angles, filters the robot out, fits a circle");
  r.add<SequencerNode>("hydrus_fitting", "sequencer",
                       "switches the sensors' lasers so that no two whose views overlap emit at once (Algorithm 4)");
#if TINYLINE_HYDRUS_WITH_SIM
  r.add<HydrusSimNode>("hydrus_fitting", "hydrus_sim",
                       "flies the simulated Hydrus of a scene through the grasp: moves its links and sensors, "
                       "publishes joint states and the true cylinder");
#endif
}

}  // namespace tinyline::hydrus_fitting
