// SPDX-License-Identifier: Apache-2.0
// The evaluation's world is chosen by ScenarioOptions::truss (tomato_eval
// --truss-set): the scenario's truss and truth follow it.
#include <gtest/gtest.h>

#include "tomato_reasoning/eval/scenario.hpp"

namespace eval = tinyline::tomato_reasoning::eval;
namespace sim = tinyline::sim;

TEST(ScenarioWorld, TheTrussOptionsReachTheScenario) {
  eval::ScenarioOptions o;
  const eval::Scenario pendulum = eval::make_scenario(sim::TrussClass::kB, 7, o);
  ASSERT_TRUE(sim::set_truss_option(o.truss, "physics", "elastic_rod").ok());
  ASSERT_TRUE(sim::set_truss_option(o.truss, "pedicel_leaves", "1").ok());
  const eval::Scenario rod = eval::make_scenario(sim::TrussClass::kB, 7, o);
  EXPECT_EQ(pendulum.truss.params.physics, sim::TrussPhysics::kPendulum);
  EXPECT_EQ(rod.truss.params.physics, sim::TrussPhysics::kElasticRod);
  EXPECT_EQ(rod.truss.params.complexity, sim::TrussClass::kB);
  EXPECT_EQ(rod.truss.params.seed, 7u);
  ASSERT_FALSE(rod.truss.tomatoes.empty());
  EXPECT_EQ(pendulum.truss.tomatoes.front().pedicel_path_m.size(), 2u);
  EXPECT_EQ(rod.truss.tomatoes.front().pedicel_path_m.size(), std::size_t(o.truss.pedicel_segments + 1));
  // The truth's pedicel direction is the settled fruit's axis, in the camera frame.
  const Eigen::Vector3d axis = rod.truss.T_world_camera.inverse().linear() * rod.truss.tomatoes.front().pedicel_dir;
  EXPECT_LT((rod.truth.front().pedicel_dir - axis).norm(), 1e-12);
  int leaves = 0;
  for (std::size_t k = 0; k < rod.world.size(); ++k)
    leaves += rod.world.object(static_cast<sim::ObjectId>(k)).name.find("_leaf_pedicel_") != std::string::npos;
  EXPECT_EQ(leaves, 1);
}
