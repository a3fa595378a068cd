// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/scoring.hpp"
#include "tomato_reasoning/pipeline.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

TEST(Pipeline, FindsEveryTomatoOfASimpleTrussWithinAFewMillimetres) {
  const eval::Scenario s = eval::make_scenario(sim::TrussClass::kA, 3);
  PipelineParams p;
  p.gravity = s.gravity_camera;
  const PipelineResult r = TomatoPipeline(p).run(s.cloud());
  ASSERT_TRUE(r.ok) << r.stage << ": " << r.reason;
  const eval::TrussScore sc = eval::score_truss(s, r);
  EXPECT_EQ(sc.detected, sc.truth);
  EXPECT_EQ(sc.unmatched, 0);
  for (const auto& t : sc.tomatoes) {
    EXPECT_LT(t.centre_error_m, 0.005);
    EXPECT_LT(std::abs(t.radius_error_m), 0.003);
  }
  EXPECT_EQ(r.pick_order.size(), r.tomatoes.size());
  EXPECT_GT(r.times.total_ms(), 0.0);
  for (const auto& t : r.tomatoes) EXPECT_GE(t.pick_rank, 0);
}

TEST(Pipeline, TwoViewsRecoverFruitOneViewCannotSee) {
  eval::ScenarioOptions two;
  two.views = 2;
  int one_view = 0, two_views = 0, truth = 0;
  for (std::uint64_t seed : {1002u, 1004u}) {  // dense class C trusses with hidden fruit
    const eval::Scenario s = eval::make_scenario(sim::TrussClass::kC, seed, two);
    PipelineParams p;
    p.gravity = s.gravity_camera;
    const TomatoPipeline pipe(p);
    std::vector<View> views;
    for (std::size_t v = 0; v < s.clouds.size(); ++v) views.push_back({s.clouds[v], s.T_ref_camera[v]});
    two_views += eval::score_truss(s, pipe.run(views)).detected;
    one_view += eval::score_truss(s, pipe.run(s.cloud())).detected;
    truth += static_cast<int>(s.truth.size());
  }
  EXPECT_GT(two_views, one_view);
  EXPECT_GE(two_views, truth - 1);
}

TEST(Pipeline, BadInputStopsWithTheStageAndTheReason) {
  const TomatoPipeline pipe;
  ColorCloud empty;
  PipelineResult r = pipe.run(empty);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.stage, "input");
  EXPECT_EQ(r.reason, "empty cloud");

  ColorCloud nan;
  for (int k = 0; k < 100; ++k) nan.push_back({NAN, NAN, NAN}, {200, 40, 30});
  r = pipe.run(nan);
  EXPECT_EQ(r.stage, "hsi");
  EXPECT_NE(r.reason.find("depth"), std::string::npos);

  ColorCloud green;
  for (int k = 0; k < 100; ++k) green.push_back({0.001f * k, 0, 0.5f}, {60, 130, 40});
  EXPECT_EQ(pipe.run(green).stage, "hsi");

  ColorCloud one;
  one.push_back({0, 0, 0.5f}, {200, 40, 30});
  r = pipe.run(one);
  EXPECT_EQ(r.stage, "branch");

  // A flat red card: plenty of red points, no sphere.
  ColorCloud card;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) card.push_back({0.001f * i, 0.001f * j, 0.5f}, {200, 40, 30});
  r = pipe.run(card);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.stage, "spheres");
  EXPECT_TRUE(r.tomatoes.empty());

  ColorCloud broken = card;
  broken.width = 7;
  EXPECT_EQ(pipe.run(broken).stage, "input");
  EXPECT_EQ(pipe.run(std::vector<View>{}).stage, "input");
  View no_cloud;
  EXPECT_EQ(pipe.run(std::vector<View>{no_cloud}).stage, "input");

  PipelineParams bad;
  bad.gravity = Eigen::Vector3d::Zero();
  EXPECT_THROW(TomatoPipeline{bad}, std::invalid_argument);
  EXPECT_EQ(pipe.reason_about({}).stage, "spheres");
}
