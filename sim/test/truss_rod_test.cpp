// SPDX-License-Identifier: Apache-2.0
// The elastic-rod truss physics (scenes/truss_rod.hpp): checked against beam
// theory computed here independently, and on whole trusses.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include <sim/scene.hpp>
#include <sim/scenes/truss.hpp>
#include <sim/scenes/truss_rod.hpp>

using namespace tinyline::sim;

namespace {

constexpr double kG = 9.81;

// A horizontal cantilever along +x, clamped at the origin, of `segments`
// elements, with a point mass at the tip (a fruit of zero radius).
struct Cantilever {
  rod::Network net;
  int tip = -1;
};

Cantilever cantilever(double length, double E, double radius, int segments, double tip_mass) {
  Cantilever c;
  const double l = length / segments, EI = E * rod::round_section_inertia(radius);
  const int ghost = c.net.add_node({-l, 0, 0}, true);
  int prev = ghost, cur = c.net.add_node({0, 0, 0}, true);
  for (int k = 1; k <= segments; ++k) {
    const int next = c.net.add_node({k * l, 0, 0});
    c.net.add_segment(cur, next, 1e3 * E * M_PI * radius * radius);  // practically inextensible
    // The clamp's hinge stands for half an element: twice the stiffness.
    c.net.add_hinge(prev, cur, cur, next, (k == 1 ? 2.0 : 1.0) * EI / l);
    prev = cur;
    cur = next;
  }
  c.tip = cur;
  c.net.bodies.push_back({cur, -2, 0.0, tip_mass});
  return c;
}

// The elastica of a cantilever under a tip load (no rod weight): EI theta'' =
// -P cos(theta), theta(0) = 0, theta'(L) = 0, by shooting on theta'(0) with
// RK4; returns the tip's drop / L. alpha = P L^2 / EI.
double elastica_drop(double alpha) {
  auto shoot = [&](double k0, double* drop) {
    const int n = 4000;
    const double h = 1.0 / n;
    double th = 0.0, w = k0, y = 0.0;
    for (int i = 0; i < n; ++i) {
      auto f = [&](double t, double ww) { return std::array<double, 3>{ww, -alpha * std::cos(t), std::sin(t)}; };
      const auto a = f(th, w);
      const auto b = f(th + 0.5 * h * a[0], w + 0.5 * h * a[1]);
      const auto c = f(th + 0.5 * h * b[0], w + 0.5 * h * b[1]);
      const auto d = f(th + h * c[0], w + h * c[1]);
      th += h / 6 * (a[0] + 2 * b[0] + 2 * c[0] + d[0]);
      w += h / 6 * (a[1] + 2 * b[1] + 2 * c[1] + d[1]);
      y += h / 6 * (a[2] + 2 * b[2] + 2 * c[2] + d[2]);
    }
    if (drop) *drop = y;
    return w;  // theta'(L): must vanish
  };
  double lo = 0.0, hi = alpha;  // theta'(L) > 0 at lo, < 0 at hi
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (shoot(mid, nullptr) > 0 ? hi : lo) = mid;
  }
  double drop = 0.0;
  shoot(0.5 * (lo + hi), &drop);
  return drop;
}

double tip_drop(double alpha, double length, double E, double radius) {
  const double EI = E * rod::round_section_inertia(radius);
  const double mass = alpha * EI / (length * length) / kG;
  Cantilever c = cantilever(length, E, radius, 40, mass);
  rod::SettleOptions o;
  o.tolerance_n = 1e-7 * mass * kG;
  o.max_iterations = 2000000;
  const rod::SettleReport r = rod::settle(c.net, o);
  EXPECT_TRUE(r.converged) << "residual " << r.max_residual_n << " N after " << r.iterations;
  return -c.net.x[std::size_t(c.tip)].z();
}

}  // namespace

TEST(TrussRod, AStiffCantileverDropsAsLinearBeamTheorySays) {
  // P L^2 / EI = 0.02: the linear theory's P L^3 / (3 EI) holds to 0.1 %.
  const double L = 0.03, E = 5e6, r = 0.003;
  const double drop = tip_drop(0.02, L, E, r);
  EXPECT_NEAR(drop / L, 0.02 / 3.0, 0.02 * 0.02 / 3.0);
}

TEST(TrussRod, ASoftCantileverFollowsTheElastica) {
  // P L^2 / EI = 2: far beyond linear theory (which would say 0.667 L); the
  // large-deflection elastica, integrated here, says about 0.49 L.
  const double L = 0.03, E = 5e6, r = 0.003;
  const double expected = elastica_drop(2.0);
  EXPECT_GT(expected, 0.45);
  EXPECT_LT(expected, 0.55);
  EXPECT_NEAR(tip_drop(2.0, L, E, r) / L, expected, 0.02 * expected);
}

TEST(TrussRod, FrictionHoldsAFruitOnASlopeThatAFrictionlessContactLetsSlide) {
  // Two fruit hanging side by side from pedicels tilted towards each other:
  // with friction the contact force leaves the line of centres.
  auto run = [](double mu) {
    rod::Network net;
    std::vector<int> centres;
    for (int side : {-1, 1}) {  // unequal fruit, so that the touch would slide
      const Eigen::Vector3d anchor(side * 0.03, 0, 0);
      const Eigen::Vector3d dir = Eigen::Vector3d(-side * 0.5, 0, -1).normalized();
      const int g = net.add_node(anchor - 0.005 * dir, true);
      const int a = net.add_node(anchor, true);
      const int b = net.add_node(anchor + 0.01 * dir);
      const int c = net.add_node(anchor + 0.04 * dir);
      net.add_segment(a, b, 200.0);
      net.add_segment(b, c, 2000.0);
      net.add_hinge(g, a, a, b, 0.02);
      net.add_hinge(a, b, b, c, 1.0);
      net.bodies.push_back({c, int(centres.size()), 0.03, side < 0 ? 0.08 : 0.2});
      centres.push_back(c);
    }
    rod::SettleOptions o;
    o.friction = mu;
    const rod::SettleReport r = rod::settle(net, o);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(r.contacts.size(), 1u);
    EXPECT_LT(r.max_penetration_m, 2e-4);
    return r.contacts.empty() ? 0.0 : r.contacts[0].tangential_n / std::max(r.contacts[0].normal_n, 1e-12);
  };
  EXPECT_LT(run(0.0), 1e-9);
  const double with = run(0.5);
  EXPECT_GT(with, 0.0);
  EXPECT_LE(with, 0.5 + 1e-9);  // Coulomb: never beyond mu
}

TEST(TrussRod, ElasticTrussesSettleWithoutInterpenetration) {
  for (TrussClass c : {TrussClass::kA, TrussClass::kB, TrussClass::kC}) {
    for (std::uint64_t seed = 1; seed <= 6; ++seed) {
      TrussParams p;
      p.complexity = c;
      p.seed = seed;
      p.physics = TrussPhysics::kElasticRod;
      const Truss t = make_truss(p);
      SCOPED_TRACE(std::string("class ") + static_cast<char>(c) + " seed " + std::to_string(seed));
      ASSERT_TRUE(t.relaxation.converged)
          << "residual " << t.relaxation.max_torque_residual << ", penetration " << t.relaxation.max_penetration_m
          << ", " << t.relaxation.iterations << " iterations";
      EXPECT_LT(t.relaxation.max_torque_residual, 1e-3);
      for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
        const auto& a = t.tomatoes[i];
        ASSERT_EQ(a.pedicel_path_m.size(), std::size_t(p.pedicel_segments + 1));
        EXPECT_NEAR(a.pedicel_dir.norm(), 1.0, 1e-12);
        // The fruit's axis is the pedicel's tangent at the calyx, and the
        // centre sits a polar radius below the calyx along it.
        EXPECT_NEAR((a.calyx_m - a.centre_m).norm(), a.polar_radius_m, 5e-4);
        for (std::size_t j = i + 1; j < t.tomatoes.size(); ++j) {
          const auto& b = t.tomatoes[j];
          EXPECT_GE((a.centre_m - b.centre_m).norm(), a.bounding_radius_m + b.bounding_radius_m - 5e-4)
              << i << " overlaps " << j;
        }
      }
    }
  }
}

TEST(TrussRod, PedicelsCurveSoTheFruitAxisIsNotTheAnchorLine) {
  double largest = 0.0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    TrussParams p;
    p.complexity = TrussClass::kB;
    p.seed = seed;
    p.physics = TrussPhysics::kElasticRod;
    for (const auto& t : make_truss(p).tomatoes) {
      const double off = std::acos(std::clamp(t.pedicel_dir.dot((t.anchor_m - t.centre_m).normalized()), -1.0, 1.0));
      largest = std::max(largest, off * 180.0 / M_PI);
    }
  }
  EXPECT_GT(largest, 5.0);
}

TEST(TrussRod, ThePeduncleSagsUnderTheFruit) {
  int compared = 0;
  double drop = 0.0;
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    TrussParams p;
    p.complexity = TrussClass::kC;
    p.seed = seed;
    const Truss pend = make_truss(p);
    p.physics = TrussPhysics::kElasticRod;
    const Truss rod = make_truss(p);
    if (pend.relaxation.restarts != 0 || rod.relaxation.restarts != 0) continue;  // not the same drawn layout
    ++compared;
    // The root is where it was; the free end is lower on average (a
    // single truss's end can rise where stiff knuckles twist it).
    EXPECT_LT((rod.peduncle_m.front() - pend.peduncle_m.front()).norm(), 1e-12);
    drop += pend.peduncle_m.back().z() - rod.peduncle_m.back().z();
  }
  ASSERT_GE(compared, 4);
  EXPECT_GT(drop / compared, 0.005);
}

TEST(TrussRod, PathsRoundTripThroughTheSceneAndPendulumScenesStayStraight) {
  TrussParams p;
  p.seed = 5;
  p.physics = TrussPhysics::kElasticRod;
  const Scene s = make_truss_scene(p);
  const TrussTruth back = truss_truth_from_scene(s);
  const Truss t = make_truss(p);
  ASSERT_EQ(back.tomatoes.size(), t.tomatoes.size());
  for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
    ASSERT_EQ(back.tomatoes[i].pedicel_path_m.size(), t.tomatoes[i].pedicel_path_m.size());
    EXPECT_LT((back.tomatoes[i].pedicel_path_m.back() - t.tomatoes[i].calyx_m).norm(), 1e-12);
  }
  p.physics = TrussPhysics::kPendulum;
  const Scene straight = make_truss_scene(p);
  EXPECT_EQ(straight.truth.count("truss_pedicel_paths_m"), 0u);
  EXPECT_EQ(truss_truth_from_scene(straight).tomatoes[0].pedicel_path_m.size(), 2u);
}

TEST(TrussRod, SceneOptionsAreSetByNameAndBadOnesAreRefused) {
  TrussParams p;
  EXPECT_TRUE(set_truss_option(p, "physics", "elastic_rod").ok());
  EXPECT_EQ(p.physics, TrussPhysics::kElasticRod);
  EXPECT_TRUE(set_truss_option(p, "stem_bend_deg", "30").ok());
  EXPECT_DOUBLE_EQ(p.stem_bend_deg, 30.0);
  EXPECT_TRUE(set_truss_option(p, "pedicel_leaves", "2").ok());
  EXPECT_EQ(p.pedicel_leaves, 2);
  EXPECT_FALSE(set_truss_option(p, "physics", "jelly").ok());
  EXPECT_FALSE(set_truss_option(p, "friction", "nan").ok());
  EXPECT_FALSE(set_truss_option(p, "friction", "0.5x").ok());
  EXPECT_FALSE(set_truss_option(p, "pedicel_leaves", "1.5").ok());
  EXPECT_FALSE(set_truss_option(p, "stem_bend_deg", "500").ok());
  const auto unknown = set_truss_option(p, "wobble", "1");
  EXPECT_FALSE(unknown.ok());
  EXPECT_NE(unknown.message.find("wobble"), std::string::npos);
}

TEST(TrussRod, CurvedStemsAndPedicelLeavesAppearInTheWorld) {
  TrussParams p;
  p.seed = 2;
  p.stem_bend_deg = 40;
  p.peduncle_curl_deg = 60;
  p.pedicel_leaves = 2;
  const Scene s = make_truss_scene(p);
  int stem_pieces = 0, pedicel_leaves = 0;
  for (std::size_t k = 0; k < s.world.size(); ++k) {
    const std::string& n = s.world.object(static_cast<ObjectId>(k)).name;
    stem_pieces += n.rfind("truss_main_stem", 0) == 0;
    pedicel_leaves += n.rfind("truss_leaf_pedicel_", 0) == 0;
  }
  EXPECT_EQ(stem_pieces, 8);
  EXPECT_EQ(pedicel_leaves, 2);
}

TEST(TrussRod, SceneFilesChooseThePhysicsAndRefuseAnUnknownOne) {
  const Scene s = load_scene_string(
      "name: t\ngenerators:\n  - {type: truss, class: C, seed: 4, physics: elastic_rod, stem_bend_deg: 20, "
      "pedicel_leaves: 1}\n",
      "inline.yaml", ".");
  const TrussTruth truth = truss_truth_from_scene(s);
  ASSERT_FALSE(truth.tomatoes.empty());
  EXPECT_EQ(truth.tomatoes[0].pedicel_path_m.size(), 5u);
  try {
    (void)load_scene_string("name: t\ngenerators:\n  - {type: truss, physics: jelly}\n", "bad.yaml", ".");
    ADD_FAILURE() << "an unknown physics was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("elastic_rod"), std::string::npos) << e.what();
  }
}
