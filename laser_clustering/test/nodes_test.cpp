// SPDX-License-Identifier: Apache-2.0
// The laser_clustering nodes on the bus: built by name with remaps and
// parameters, fed LineScan messages, stepped by the deterministic executor
// on sim time (no sleeps). The tests of each node are in <node>_node_test.cpp;
// here, what holds for all of them.

#include "node_rig.hpp"

TEST(LaserClusteringNodes, AllFourAreRegistered) {
  bus::NodeRegistry r;
  lc::register_nodes(r);
  for (const char* t : {"line_clusterer", "pedicel_finder", "tomato_registration", "reflectance_clusterer",
                        "alignment_search", "pitch_sweep"}) {
    EXPECT_NE(r.find("laser_clustering", t), nullptr) << t;
  }
}

TEST(LaserClusteringNodes, BadParametersStopTheNodeWithTheReason) {
  Harness h;
  bus::NodeOptions o;
  o.name = "finder";
  o.param("min_range_m", 0.5).param("max_range_m", 0.2);
  try {
    h.add("pedicel_finder", o);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("min_range_m < max_range_m"));
  }
  bus::NodeOptions u;
  u.name = "clusterer";
  u.param("groups_eps", 0.02);  // not a parameter (groups_eps_m is)
  EXPECT_THROW(h.add("line_clusterer", u), bus::ParamError);
  bus::NodeOptions r;
  r.name = "refl";
  r.param("eps_m", -1.0);
  EXPECT_THROW(h.add("reflectance_clusterer", r), bus::ParamError);
}
