// SPDX-License-Identifier: Apache-2.0
// Every package's nodes, registered by name. A package left out of the build
// (TINYLINE_PACKAGES) is left out here by its TINYLINE_WITH_* definition
// (tools/CMakeLists.txt); adding a package adds its two lines below.
#include <tinyline/bus/registry.hpp>
#include <tinyline/tools/nodes.hpp>

#include "register_all.hpp"

#ifdef TINYLINE_WITH_BAG
#include <tinyline/bag/register.hpp>
#endif
#ifdef TINYLINE_WITH_SIM
#include <sim/nodes/register.hpp>
#endif
#ifdef TINYLINE_WITH_TINY_LASER_DRIVER
#include <tiny_laser_driver/nodes/register.hpp>
#endif
#ifdef TINYLINE_WITH_LASER_CLUSTERING
#include <laser_clustering/nodes/register.hpp>
#endif
#ifdef TINYLINE_WITH_TOMATO_REASONING
#include <tomato_reasoning/nodes/register.hpp>
#endif
#ifdef TINYLINE_WITH_TOMATO_REASONING_SIM
#include <tomato_reasoning/sim/register.hpp>
#endif
#ifdef TINYLINE_WITH_HYDRUS_FITTING
#include <hydrus_fitting/nodes/register.hpp>
#endif
#ifdef TINYLINE_WITH_HYDRUS_FITTING_SIM
#include <hydrus_fitting/sim/register.hpp>
#endif

namespace tinyline::tools {

void register_all_nodes(bus::NodeRegistry& r) {
  register_nodes(r);
#ifdef TINYLINE_WITH_SIM
  sim::register_nodes(r);
#endif
#ifdef TINYLINE_WITH_TINY_LASER_DRIVER
  tiny_laser_driver::register_nodes(r);
#endif
#ifdef TINYLINE_WITH_LASER_CLUSTERING
  laser_clustering::register_nodes(r);
#endif
#ifdef TINYLINE_WITH_TOMATO_REASONING
  tomato_reasoning::register_nodes(r);
#endif
#ifdef TINYLINE_WITH_TOMATO_REASONING_SIM
  tomato_reasoning::register_sim_nodes(r);
#endif
#ifdef TINYLINE_WITH_HYDRUS_FITTING
  hydrus_fitting::register_nodes(r);
#endif
#ifdef TINYLINE_WITH_HYDRUS_FITTING_SIM
  hydrus_fitting::register_sim_nodes(r);
#endif
#ifdef TINYLINE_WITH_BAG
  bag::register_nodes(r);
#endif
}

}  // namespace tinyline::tools
