// SPDX-License-Identifier: Apache-2.0
#include <cmath>

#include <gtest/gtest.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/scoring.hpp"
#include "tomato_reasoning/pedicel_evidence.hpp"
#include "tomato_reasoning/pipeline.hpp"

#include <tinyline/common/random.hpp>

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

double deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// The near side of a 6 mm pedicel leaving a fruit at `c` (radius r) along
// unit `dir`, seen from the origin: points every 2 mm from the calyx out.
GreenPoints seen_pedicel(const Eigen::Vector3d& c, double r, const Eigen::Vector3d& dir) {
  GreenPoints g;
  g.viewpoints = {Eigen::Vector3f::Zero()};
  for (double s = r; s <= r + 0.02; s += 0.002) {
    const Eigen::Vector3d axis = c + s * dir;
    for (int k = -1; k <= 1; ++k) {
      const Eigen::Vector3d side = dir.cross(axis.normalized()).normalized();
      Eigen::Vector3d p = axis + 0.002 * k * side;
      p -= 0.003 * p.normalized();  // the surface facing the camera
      g.xyz.push_back(p.cast<float>());
      g.view.push_back(0);
    }
  }
  return g;
}

}  // namespace

TEST(PedicelEvidence, ASeenPedicelGivesItsDirectionAndThePosteriorFollowsIt) {
  const Sphere s{{0.0, 0.0, 0.45}, 0.03};
  const Eigen::Vector3d gravity(0, 1, 0);
  const Eigen::Vector3d truth = Eigen::Vector3d(0.4, -1.0, -0.2).normalized();  // 24 deg off straight up
  const auto prior = estimate_pedicels({s}, {}, gravity, ForceModelParams{});
  ASSERT_EQ(prior.size(), 1u);
  const PedicelSighting seen =
      sight_pedicel(seen_pedicel(s.centre, s.radius_m, truth), {s}, 0, prior[0].expected_dir, s.radius_m + 0.008);
  ASSERT_TRUE(seen.seen);
  EXPECT_LT(deg(seen.direction, truth), 2.0);
  EXPECT_TRUE(seen.cut_point_seen);
  EXPECT_LT((seen.cut_point - (s.centre + 0.038 * truth)).norm(), 0.002);
  const PedicelEstimate post = pedicel_posterior(prior[0], seen, gravity);
  // Between the prior and the seen direction (the likelihood's concentration
  // is capped near the prior's kernel), well off the prior towards the truth.
  const double prior_err = deg(prior[0].expected_dir, truth), post_err = deg(post.expected_dir, truth);
  EXPECT_GT(prior_err, 20.0);
  EXPECT_LT(post_err, prior_err - 5.0);
  EXPECT_NEAR(deg(prior[0].expected_dir, post.expected_dir) + deg(post.expected_dir, seen.direction),
              deg(prior[0].expected_dir, seen.direction), 1.0);
  EXPECT_LT(post.spread50_deg, prior[0].spread50_deg);
}

TEST(PedicelEvidence, NothingSeenLeavesThePriorAsItWas) {
  const Sphere s{{0.0, 0.0, 0.45}, 0.03};
  const auto prior = estimate_pedicels({s}, {}, Eigen::Vector3d(0, 1, 0), ForceModelParams{});
  GreenPoints none;
  none.viewpoints = {Eigen::Vector3f::Zero()};
  const PedicelSighting seen = sight_pedicel(none, {s}, 0, prior[0].expected_dir, 0.038);
  EXPECT_FALSE(seen.seen);
  const PedicelEstimate post = pedicel_posterior(prior[0], seen, Eigen::Vector3d(0, 1, 0));
  EXPECT_EQ(post.expected_dir, prior[0].expected_dir);
  EXPECT_EQ(post.distribution.draws(), prior[0].distribution.draws());
}

TEST(PedicelEvidence, ANeighboursPedicelIsNotThisFruitsEvidence) {
  // Green points nearer another fruit's surface than this one's are its.
  const Sphere a{{0.0, 0.0, 0.45}, 0.03}, b{{0.058, 0.0, 0.45}, 0.03};
  const Eigen::Vector3d up(0, -1, 0);
  const GreenPoints g = seen_pedicel(b.centre, b.radius_m, up);
  const PedicelSighting seen = sight_pedicel(g, {a, b}, 0, up, 0.038);
  EXPECT_FALSE(seen.seen) << seen.points << " points";
}

TEST(PedicelEvidence, OnSimulatedElasticRodTrussesThePosteriorBeatsTheForceModel) {
  eval::ScenarioOptions o;
  o.views = 2;
  ASSERT_TRUE(sim::set_truss_option(o.truss, "physics", "elastic_rod").ok());
  std::vector<double> prior, post;
  for (std::uint64_t seed : {1u, 2u, 3u}) {  // tuning seeds
    const eval::Scenario s = eval::make_scenario(sim::TrussClass::kB, seed, o);
    PipelineParams p;
    p.gravity = s.gravity_camera;
    std::vector<View> views;
    for (std::size_t v = 0; v < s.clouds.size(); ++v) views.push_back({s.clouds[v], s.T_ref_camera[v]});
    for (const auto& t : eval::score_truss(s, TomatoPipeline(p).run(views)).tomatoes) {
      if (!t.pedicel_seen) continue;
      prior.push_back(t.prior_pedicel_error_deg);
      post.push_back(t.pedicel_error_deg);
    }
  }
  ASSERT_GE(post.size(), 4u);
  EXPECT_LT(eval::percentile(post, 50), eval::percentile(prior, 50));
}
