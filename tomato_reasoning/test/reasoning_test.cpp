// SPDX-License-Identifier: Apache-2.0
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tomato_reasoning/reasoning.hpp"

using namespace tinyline::tomato_reasoning;

namespace {
const Eigen::Vector3d kDown(0, 0, -1);  // gravity in these tests' frame (z up)
double deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / M_PI;
}
}  // namespace

TEST(ContactGraph, Equation4_17WithTolerance) {
  const std::vector<Sphere> s{{{0, 0, 0}, 0.03}, {{0.065, 0, 0}, 0.03}, {{0.2, 0, 0}, 0.03}, {{0.0, 0.058, 0}, 0.03}};
  const auto e = contact_graph(s, 0.01);
  ASSERT_EQ(e.size(), 2u);  // 0-1 (gap 5 mm), 0-3 (overlap 2 mm); 2 is alone
  EXPECT_EQ(e[0].i, 0);
  EXPECT_EQ(e[0].j, 1);
  EXPECT_NEAR(e[0].gap_m, 0.005, 1e-12);
  EXPECT_EQ(e[1].j, 3);
  EXPECT_TRUE(contact_graph(s, 0.001).empty());
}

TEST(ForceModel, TruncatedNormalMeanMatchesMonteCarlo) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.3, 0.5);
  double s = 0;
  int k = 0;
  while (k < 400000) {
    const double x = n(rng);
    if (x < 0 || x >= 1) continue;
    s += x;
    ++k;
  }
  EXPECT_NEAR(truncated_normal_mean(0.3, 0.25, 1.0), s / k, 0.002);
}

TEST(ForceModel, ALoneTomatoHangsFromAPedicelStraightUp) {
  ForceModelParams p;
  p.kernel_kappa = 0;
  const auto e = estimate_pedicels({{{0, 0, 1}, 0.03}}, {}, kDown, p);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].edges, 0);
  EXPECT_LT(deg(e[0].expected_dir, {0, 0, 1}), 1e-9);
  EXPECT_LT(e[0].spread90_deg, 2.6);  // the 5 deg top-hat cell only
  EXPECT_NEAR(e[0].gravity_angle_rad, 0.0, 1e-9);
}

TEST(ForceModel, ANeighbourTiltsThePedicelTowardsIt) {
  // Two fruit side by side, touching: each is pushed away from the other,
  // so its pedicel pulls up and towards the neighbour (Eq. 4.22).
  const std::vector<Sphere> s{{{0, 0, 1}, 0.03}, {{0.06, 0, 1}, 0.03}};
  const auto edges = contact_graph(s, 0.01);
  ASSERT_EQ(edges.size(), 1u);
  ForceModelParams p;
  p.kernel_kappa = 0;
  const auto e = estimate_pedicels(s, edges, kDown, p);
  EXPECT_GT(e[0].expected_dir.x(), 0.1);
  EXPECT_LT(e[1].expected_dir.x(), -0.1);
  EXPECT_GT(e[0].expected_dir.z(), 0.8);
  // E[F_ip] = -(G + E[eps] theta r e): tan(tilt) = E[eps] for equal radii.
  const double tilt = std::atan(truncated_normal_mean(0.3, 0.25, 1.0));
  EXPECT_NEAR(deg(e[0].expected_dir, {0, 0, 1}), tilt * 180 / M_PI, 1e-6);
  EXPECT_NEAR(e[0].expected_dir.x(), -e[1].expected_dir.x(), 1e-9);
  // Without a kernel every draw lies in the plane of gravity and the edge.
  for (const auto& d : e[0].distribution.draws()) EXPECT_NEAR(d.y(), 0.0, 1e-12);
  // eps in [0, 1): the tilt stays between plumb and 45 degrees.
  for (const auto& d : e[0].distribution.draws()) EXPECT_LE(deg(d, {0, 0, 1}), 45.0 + 1e-9);
}

TEST(PedicelDistribution, HpdRegionHoldsItsMassAndTheKernelSpreadsIt) {
  ForceModelParams p;
  p.kernel_kappa = 60;
  const std::vector<Sphere> s{{{0, 0, 1}, 0.03}, {{0.06, 0, 1}, 0.03}, {{0.0, 0.06, 1.0}, 0.03}};
  const auto e = estimate_pedicels(s, contact_graph(s, 0.01), kDown, p);
  const PedicelDistribution& d = e[0].distribution;
  // Directions drawn from the distribution itself fall inside its HPD50
  // region half of the time: the region is calibrated by construction.
  const auto xs = d.sample(2000, 12345);
  int in = 0;
  const double level = d.hpd_level(0.5, 2000);
  for (const auto& x : xs) in += d.density(x) >= level;
  EXPECT_NEAR(in / 2000.0, 0.5, 0.05);
  EXPECT_TRUE(d.in_hpd(e[0].expected_dir, 0.5));
  EXPECT_FALSE(d.in_hpd(-e[0].expected_dir, 0.5));
  // The density integrates to one over the sphere (grid quadrature).
  const int nphi = 144, ntheta = 72;
  const auto g = d.grid(nphi, ntheta);
  double integral = 0;
  for (int t = 0; t < ntheta; ++t)
    for (int f = 0; f < nphi; ++f)
      integral +=
          g[std::size_t(t)][std::size_t(f)] * std::sin((t + 0.5) * M_PI / ntheta) * (M_PI / ntheta) * (2 * M_PI / nphi);
  EXPECT_NEAR(integral, 1.0, 0.03);
  EXPECT_GT(e[0].spread50_deg, 3.0);
  EXPECT_GT(e[0].spread90_deg, e[0].spread50_deg);
}

TEST(PickOrder, HighLooseAndUprightFirst) {
  // 0: high, alone, upright; 1: low with two neighbours; 2, 3: its neighbours.
  const std::vector<Sphere> s{
      {{-0.3, 0, 1.2}, 0.03}, {{0, 0, 1.0}, 0.03}, {{0.06, 0, 1.0}, 0.03}, {{-0.06, 0, 1.0}, 0.03}};
  const auto edges = contact_graph(s, 0.01);
  const auto peds = estimate_pedicels(s, edges, kDown);
  const auto order = pick_order(s, peds, kDown);
  ASSERT_EQ(order.size(), 4u);
  EXPECT_EQ(order.front().sphere, 0);
  EXPECT_EQ(order.back().sphere, 1);  // two edges, lowest
  EXPECT_LT(order.front().energy_term, 0);
  EXPECT_NEAR(order.front().edge_term, 0.0, 1e-12);
  EXPECT_NEAR(order.back().edge_term, 2 * PickOrderParams{}.w_edges, 1e-12);
  for (std::size_t k = 1; k < order.size(); ++k) EXPECT_LE(order[k - 1].cost, order[k].cost);
  // Weights are parameters: with only the edge term, the loner still goes first and the middle last.
  PickOrderParams edges_only{0, 1, 0};
  EXPECT_EQ(pick_order(s, peds, kDown, edges_only).back().sphere, 1);
}

TEST(CutPlan, CoversAtLeastAsMuchAsTheExpectationAndStaysOutsideOtherFruit) {
  ForceModelParams p;
  p.kernel_kappa = 60;
  const std::vector<Sphere> s{{{0, 0, 1}, 0.03}, {{0.06, 0, 1}, 0.03}, {{0.03, 0.0, 1.075}, 0.03}};
  const auto peds = estimate_pedicels(s, contact_graph(s, 0.01), kDown, p);
  for (int i = 0; i < 3; ++i) {
    const CutPlan c = plan_cut(s, i, peds[std::size_t(i)]);
    EXPECT_GE(c.coverage + 1e-12, c.expected_coverage);
    EXPECT_GT(c.coverage, 0.0);
    EXPECT_NEAR(c.half_angle_rad, std::atan2(0.01, 0.03 + CutParams{}.cut_offset_m), 1e-12);
    if (!c.blocked) {
      for (int j = 0; j < 3; ++j)
        if (j != i) {
          EXPECT_GE((c.point - s[std::size_t(j)].centre).norm(), s[std::size_t(j)].radius_m);
        }
    }
  }
}

TEST(ForceModel, BadInputGivesNoEstimates) {
  ForceModelParams bad;
  bad.eps_variance = -1;
  EXPECT_FALSE(validate(bad).ok());
  EXPECT_TRUE(estimate_pedicels({{{0, 0, 1}, 0.03}}, {}, kDown, bad).empty());
  EXPECT_TRUE(estimate_pedicels({}, {}, kDown).empty());
  EXPECT_TRUE(estimate_pedicels({{{0, 0, 1}, 0.03}}, {}, Eigen::Vector3d::Zero()).empty());
  ForceModelParams nomass;
  nomass.eps_mean = 1.0;  // N(1, 1e-6) has no mass in [0, 0.5)
  nomass.eps_variance = 1e-6;
  nomass.eps_max = 0.5;
  EXPECT_THAT(validate(nomass).message, ::testing::HasSubstr("no mass"));
  EXPECT_TRUE(pick_order({}, {}, kDown).empty());
  EXPECT_EQ(plan_cut({}, 0, {}).coverage, 0.0);
}
