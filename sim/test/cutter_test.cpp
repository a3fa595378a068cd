// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>

#include <sim/scenes/cutter.hpp>
#include <sim/scenes/truss.hpp>

using namespace tinyline::sim;

namespace {

Truss one_tomato(std::uint64_t seed) {
  TrussParams p;
  p.complexity = TrussClass::kA;
  p.num_tomatoes = 1;
  p.seed = seed;
  return make_truss(p);
}

// The throat at `at`, the blade plane across the axis `along` (y), the
// blades pointing away from the camera side (z as near +y world as allowed).
Eigen::Isometry3d throat(const Eigen::Vector3d& at, const Eigen::Vector3d& along) {
  const Eigen::Vector3d y = along.normalized();
  Eigen::Vector3d z = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(y) * y;
  if (z.norm() < 1e-6) z = Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(y) * y;
  z.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = y.cross(z);
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = at;
  return T;
}

// Where the reasoning plans the cut: 8 mm up the pedicel from the fruit.
Eigen::Isometry3d on_pedicel(const TrussTomato& t, double above_calyx_m = 0.008) {
  const Eigen::Vector3d up = (t.anchor_m - t.calyx_m).normalized();
  return throat(t.calyx_m + above_calyx_m * up, -up);
}

}  // namespace

// Every pedicel, 8 mm above its fruit: cut, unless the pedicel is so short
// that the peduncle it hangs from is in the blades too (a cut failure).
TEST(Cutter, AThroatOnAPedicelCutsItUnlessThePeduncleIsInTheBlades) {
  int cut = 0, jammed = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Truss truss = one_tomato(seed);
    const TrussTomato& t = truss.tomatoes[0];
    const CutOutcome c = close_blades(truss, on_pedicel(t), BladeParams{}, 0);
    // The blade box reaches 2 mm up the pedicel; the peduncle is 4.5 mm thick.
    const double to_anchor = (t.anchor_m - t.calyx_m).norm() - 0.008;
    if (to_anchor > 0.002 + truss.params.peduncle_radius_m + 0.002) {
      EXPECT_EQ(c.result, CutResult::kCutTarget) << to_string(c.result) << " on " << c.object;
      EXPECT_EQ(c.tomato, 0);
      EXPECT_EQ(c.severed, std::vector<int>{0});
      ++cut;
    } else if (to_anchor < 0.002 + truss.params.peduncle_radius_m - 0.0005) {
      EXPECT_EQ(c.result, CutResult::kJammed);
      EXPECT_EQ(c.object, "peduncle");
      ++jammed;
    }
  }
  EXPECT_GE(cut, 10);
}

TEST(Cutter, WithinTheOpeningStillCutsAndThreeCentimetresOffClosesOnNothing) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {  // (seed 4's peduncle comes down into an 8 mm shift)
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Truss truss = one_tomato(seed);
    const TrussTomato& t = truss.tomatoes[0];
    const Eigen::Isometry3d T = on_pedicel(t);
    // Across the opening, towards the main stem: away from the peduncle's
    // free end, which arches down to the pedicels' height.
    Eigen::Vector3d across = T.linear().col(0);
    if (across.dot(t.anchor_m - truss.params.origin_m) > 0) across = -across;
    auto moved = [&](double dx) {
      Eigen::Isometry3d M = T;
      M.translation() += dx * across;
      return close_blades(truss, M, BladeParams{}, 0);
    };
    EXPECT_EQ(moved(0.008).result, CutResult::kCutTarget);  // the pedicel near one blade's edge
    const CutOutcome other_edge = moved(-0.008);
    EXPECT_EQ(other_edge.result, CutResult::kCutTarget) << to_string(other_edge.result) << " on " << other_edge.object;
    const CutOutcome off = moved(0.03);
    EXPECT_EQ(off.result, CutResult::kClosedOnNothing) << to_string(off.result) << " on " << off.object;
  }
}

TEST(Cutter, OnThePeduncleJams) {
  const Truss truss = one_tomato(2);
  ASSERT_GE(truss.peduncle_m.size(), 2u);
  // On the peduncle's last segment, away from the main stem and the pedicel.
  const std::size_t n = truss.peduncle_m.size();
  const Eigen::Vector3d a = truss.peduncle_m[n - 2], b = truss.peduncle_m[n - 1];
  const CutOutcome c = close_blades(truss, throat(0.5 * (a + b), b - a), BladeParams{}, 0);
  EXPECT_EQ(c.result, CutResult::kJammed);
  EXPECT_EQ(c.object, "peduncle");
  EXPECT_TRUE(c.severed.empty());
}

TEST(Cutter, IntoTheFruitJams) {
  const Truss truss = one_tomato(4);
  const TrussTomato& t = truss.tomatoes[0];
  const CutOutcome c = close_blades(truss, throat(t.centre_m, t.pedicel_dir), BladeParams{}, 0);
  EXPECT_EQ(c.result, CutResult::kJammed);
  EXPECT_EQ(c.object, "fruit 0");
}

TEST(Cutter, OnTheMainStemJams) {
  const Truss truss = one_tomato(5);
  const StemRod s = main_stem(truss);
  const CutOutcome c = close_blades(truss, throat(s.p0 + 0.2 * (s.p1 - s.p0), s.p1 - s.p0), BladeParams{}, 0);
  EXPECT_EQ(c.result, CutResult::kJammed);
  EXPECT_EQ(c.object, "main stem");
}

TEST(Cutter, MainStemIsWhereAddToWorldPutsIt) {
  const Truss truss = one_tomato(6);
  World world;
  (void)add_to_world(truss, world);
  const auto id = world.find(truss.params.name + "_main_stem");
  ASSERT_TRUE(id.has_value());
  const auto* rod = std::get_if<RodShape>(&world.object(*id).shape);
  ASSERT_NE(rod, nullptr);
  const StemRod s = main_stem(truss);
  const Eigen::Isometry3d& T = world.object(*id).T_world_object;
  EXPECT_LT((T * rod->p0 - s.p0).norm(), 1e-9);
  EXPECT_LT((T * rod->p1 - s.p1).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(rod->radius_m, s.radius_m);
}

// Two pedicels 8 mm apart, both in the 2 cm throat: their 12 mm together are
// more than the blades sever (the finger's margin is one pedicel), so the
// blades stall on them and neither fruit falls; blades that could sever 13 mm
// would cut both, and whether that is the target's cut depends on the target.
TEST(Cutter, TwoPedicelsInTheThroat) {
  TrussParams p;
  p.complexity = TrussClass::kB;
  p.num_tomatoes = 3;
  p.seed = 7;
  Truss truss = make_truss(p);
  const TrussTomato& t0 = truss.tomatoes[0];
  const Eigen::Isometry3d T = on_pedicel(t0);
  // Tomato 1's pedicel made parallel to tomato 0's, 8 mm across the opening.
  const Eigen::Vector3d shift = 0.008 * T.linear().col(0);
  TrussTomato& t1 = truss.tomatoes[1];
  const Eigen::Vector3d fruit_offset = t0.centre_m - t0.calyx_m;
  t1.anchor_m = t0.anchor_m + shift;
  t1.calyx_m = t0.calyx_m + shift;
  t1.centre_m = t1.calyx_m + 50.0 * fruit_offset;  // its fruit far away: only its pedicel is near
  const CutOutcome jam = close_blades(truss, T, BladeParams{}, 0);
  EXPECT_EQ(jam.result, CutResult::kJammed);
  EXPECT_EQ(jam.object, "pedicels 0 and 1");
  EXPECT_TRUE(jam.severed.empty());

  BladeParams strong;
  strong.max_cut_diameter_m = 0.013;
  const CutOutcome both = close_blades(truss, T, strong, 0);
  EXPECT_EQ(both.result, CutResult::kCutTarget);
  EXPECT_EQ(both.tomato, 0);
  EXPECT_EQ(both.severed, (std::vector<int>{0, 1}));
  const CutOutcome other = close_blades(truss, T, strong, 2);
  EXPECT_EQ(other.result, CutResult::kCutOtherPedicel);
  EXPECT_EQ(other.tomato, 0);
}

TEST(Cutter, ANeighboursPedicelIsCutWhenTheTargetsIsNotThere) {
  const Truss truss = one_tomato(8);
  const CutOutcome c = close_blades(truss, on_pedicel(truss.tomatoes[0]), BladeParams{}, 5);
  EXPECT_EQ(c.result, CutResult::kCutOtherPedicel);
  EXPECT_EQ(c.tomato, 0);
}

TEST(Cutter, BadParametersOrPoseAreJamsWithAReason) {
  const Truss truss = one_tomato(1);
  BladeParams bad;
  bad.opening_m = -1;
  const CutOutcome c = close_blades(truss, on_pedicel(truss.tomatoes[0]), bad, 0);
  EXPECT_EQ(c.result, CutResult::kJammed);
  EXPECT_NE(c.object.find("opening_m"), std::string::npos) << c.object;
  Eigen::Isometry3d nan = on_pedicel(truss.tomatoes[0]);
  nan.translation().x() = std::nan("");
  EXPECT_EQ(close_blades(truss, nan, BladeParams{}, 0).result, CutResult::kJammed);
}

TEST(Cutter, ACutFruitFallsOutOfTheTrussAndTheWorld) {
  TrussParams p;
  p.complexity = TrussClass::kB;
  p.num_tomatoes = 3;
  p.seed = 11;
  Truss truss = make_truss(p);
  World world;
  (void)add_to_world(truss, world);
  const TrussTomato before = truss.tomatoes[1];
  const Eigen::Isometry3d T = on_pedicel(before);
  const CutOutcome cut = close_blades(truss, T, BladeParams{}, 1);
  ASSERT_EQ(cut.result, CutResult::kCutTarget) << to_string(cut.result) << " on " << cut.object;
  // A ray at the fruit's equator from just outside, on the camera's side, hits it before, not after.
  Eigen::Vector3d u = truss.T_world_camera.translation() - before.centre_m;
  u = (u - u.dot(before.pedicel_dir) * before.pedicel_dir).normalized();
  Ray ray;
  ray.origin = before.centre_m + (before.bounding_radius_m + 0.003) * u;
  ray.dir = -u;
  const auto fruit_hit = [&] {
    const auto h = world.raycast(ray);
    return h && world.object(h->object).name.rfind(before.object_name, 0) == 0;
  };
  EXPECT_TRUE(fruit_hit());

  drop_tomato(truss, 1);
  EXPECT_TRUE(dropped(truss, 1));
  EXPECT_FALSE(dropped(truss, 0));
  EXPECT_EQ(close_blades(truss, T, BladeParams{}, 1).result, CutResult::kClosedOnNothing);
  const int moved = drop_tomato(world, truss, 1);
  EXPECT_GE(moved, 3);                         // fruit, pedicel, sepals
  EXPECT_EQ(drop_tomato(world, truss, 1), 0);  // already gone
  EXPECT_FALSE(fruit_hit());
  // The others stay.
  EXPECT_EQ(close_blades(truss, on_pedicel(truss.tomatoes[0]), BladeParams{}, 0).result, CutResult::kCutTarget);
  EXPECT_THROW(drop_tomato(truss, 7), std::out_of_range);
}
