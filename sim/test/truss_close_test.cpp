// SPDX-License-Identifier: Apache-2.0
// The close-up truss at the gripper (sim/scenes/truss_close.hpp).
#include <gtest/gtest.h>

#include <sim/scenes/truss_close.hpp>

namespace sim = tinyline::sim;

namespace {

struct Built {
  sim::World world;
  sim::CloseTruss truss;
};

Built build(std::uint64_t seed, const sim::CloseTrussParams& p = {}) {
  Built b;
  sim::SceneRng rng(seed);
  b.truss = sim::add_close_truss(b.world, rng, seed, Eigen::Vector3d(0.01, 0.0, 0.15), 0.15, p);
  return b;
}

}  // namespace

TEST(CloseTruss, TheTargetCrossesTheLaserPlaneWhereAsked) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const auto b = build(seed);
    const sim::HangingTomato& t = b.truss.hangings.front();
    const double along = -t.top.y() / t.dir.y();  // the axis meets y = 0
    EXPECT_GT(along, 0.2 * t.length - 1e-12);
    EXPECT_LT(along, 0.8 * t.length + 1e-12);
    EXPECT_LT((t.top + along * t.dir - Eigen::Vector3d(0.01, 0.0, 0.15)).norm(), 1e-12) << seed;
  }
}

TEST(CloseTruss, NeighboursHangBesideTheTargetWithoutTouchingIt) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const auto b = build(seed);
    ASSERT_GE(b.truss.hangings.size(), 2u) << seed;
    for (std::size_t i = 0; i < b.truss.hangings.size(); ++i) {
      const auto& a = b.truss.hangings[i];
      EXPECT_EQ(b.world.object(a.pedicel).name, (i == 0 ? "target" : "neighbour" + std::to_string(i)) + "_pedicel");
      for (std::size_t j = i + 1; j < b.truss.hangings.size(); ++j) {
        const auto& c = b.truss.hangings[j];
        EXPECT_GE((a.tomato_centre - c.tomato_centre).norm(), a.tomato_radius + c.tomato_radius) << seed;
      }
    }
    EXPECT_EQ(b.world.object(b.truss.stem).name, "stem0");
  }
}

TEST(CloseTruss, TheSameSeedBuildsTheSameTruss) {
  sim::CloseTrussParams bowed;
  bowed.stem_bow_m = 0.03;
  const auto a = build(7, bowed), b = build(7, bowed);
  ASSERT_EQ(a.world.size(), b.world.size());
  for (std::size_t k = 0; k < a.world.size(); ++k) {
    const auto id = static_cast<sim::ObjectId>(k);
    EXPECT_EQ(a.world.object(id).name, b.world.object(id).name);
  }
  ASSERT_EQ(a.truss.hangings.size(), b.truss.hangings.size());
  for (std::size_t i = 0; i < a.truss.hangings.size(); ++i)
    EXPECT_EQ(a.truss.hangings[i].tomato_centre, b.truss.hangings[i].tomato_centre);
}
