// SPDX-License-Identifier: Apache-2.0
// Helpers the harvesting demo's simulator nodes share (truss_nodes.cpp,
// harvest_nodes.cpp).
#pragma once

#include <string>

#include <Eigen/Core>

#include <tinyline/bus/node.hpp>
#include <tinyline/bus/params.hpp>
#include <tinyline/bus/registry.hpp>

#include <sim/scenes/cutter.hpp>
#include <sim/scenes/truss.hpp>

namespace tinyline::tomato_reasoning::sim_nodes {

/// tomato_reasoning/sim_gripper, tomato_reasoning/harvest_score (harvest_nodes.cpp).
void register_harvest_nodes(bus::NodeRegistry& registry);

/// The node's truss_class parameter as a class; a ParamError naming the node otherwise.
inline sim::TrussClass truss_class(const bus::Node& n, const std::string& s) {
  const auto c = sim::parse_truss_class(s);
  if (!c) throw bus::ParamError({}, "node '" + n.full_name() + "': truss_class '" + s + "' is not A, B or C");
  return *c;
}

/// The world's physics by name: the elastic-rod world is the default of the
/// demo and the evaluations (its truth does not come from the reasoning's
/// own force model).
inline constexpr const char* kDefaultPhysics = "elastic_rod";
inline sim::TrussPhysics truss_physics(const bus::Node& n, const std::string& s) {
  const auto p = sim::parse_truss_physics(s);
  if (!p) throw bus::ParamError({}, "node '" + n.full_name() + "': physics '" + s + "' is not pendulum or elastic_rod");
  return *p;
}

/// The truss tomato a detected sphere is (world frame): the nearest one still
/// hanging whose true centre lies within its own radius of the detected
/// centre; -1 when none does (the detection is no tomato of this truss).
inline int match_truth(const sim::Truss& truss, const Eigen::Vector3d& centre_world) {
  int best = -1;
  double best_d = 0.0;
  for (std::size_t i = 0; i < truss.tomatoes.size(); ++i) {
    if (sim::dropped(truss, static_cast<int>(i))) continue;
    const double d = (truss.tomatoes[i].centre_m - centre_world).norm();
    if (d <= truss.tomatoes[i].radius_m && (best < 0 || d < best_d)) best = static_cast<int>(i), best_d = d;
  }
  return best;
}

}  // namespace tinyline::tomato_reasoning::sim_nodes
