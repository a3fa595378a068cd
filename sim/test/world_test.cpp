// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>

#include <sim/world.hpp>

using namespace tinyline::sim;

namespace {

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

MaterialId paper(const World& w) { return *w.materials().find("white_paper"); }

Ray ray(Eigen::Vector3d o, Eigen::Vector3d d) { return Ray{o, d.normalized()}; }

}  // namespace

TEST(World, SphereHitDistanceAndNormal) {
  World w;
  w.add({"ball", SphereShape{0.1}, at(0, 0, 1), paper(w)});
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->t_m, 0.9, 1e-12);
  EXPECT_NEAR(h->normal.z(), -1.0, 1e-12);
  EXPECT_EQ(h->object, 0);
  // Grazing miss just outside the radius.
  EXPECT_FALSE(w.raycast(ray({0.1001, 0, 0}, {0, 0, 1})));
}

TEST(World, PlaneFiniteAndInfinite) {
  World w;
  w.add({"wall", PlaneShape{}, at(0, 0, 2), paper(w)});
  w.add({"card", PlaneShape{{0.2, 0.1}}, at(0, 0, 1), paper(w)});
  auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_EQ(w.object(h->object).name, "card");
  EXPECT_NEAR(h->t_m, 1.0, 1e-12);
  // Past the card's x edge (0.1 m at 1 m) the ray reaches the wall.
  h = w.raycast(ray({0, 0, 0}, {0.15, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_EQ(w.object(h->object).name, "wall");
  EXPECT_NEAR(h->t_m, std::hypot(0.3, 2.0), 1e-9);
  // Two-sided: from behind, the normal faces the ray.
  h = w.raycast(ray({0, 0, 3}, {0, 0, -1}));
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->normal.z(), 1.0, 1e-12);
}

TEST(World, RotatedBoxAndInsideOrigin) {
  World w;
  Eigen::Isometry3d T = at(0, 0, 1);
  T.linear() = Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY()).toRotationMatrix();
  w.add({"cube", BoxShape{{0.2, 0.2, 0.2}}, T, paper(w)});
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  // A corner points at the origin: the edge is at 1 - 0.1*sqrt(2).
  EXPECT_NEAR(h->t_m, 1.0 - 0.1 * std::sqrt(2.0), 1e-9);
  // From inside, the exit face is hit.
  const auto in = w.raycast(ray({0, 0, 1}, {1, 0, 0}));
  ASSERT_TRUE(in);
  EXPECT_NEAR(in->t_m, 0.1 * std::sqrt(2.0), 1e-9);
  EXPECT_EQ(w.containing({0, 0, 1}).size(), 1u);
  EXPECT_TRUE(w.containing({0, 0, 0.5}).empty());
}

TEST(World, CylinderSideAndCap) {
  World w;
  w.add({"can", CylinderShape{0.05, 0.2}, at(0, 0, 1), paper(w)});  // axis along world z
  auto side = w.raycast(ray({-1, 0, 1}, {1, 0, 0}));
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->t_m, 0.95, 1e-12);
  EXPECT_NEAR(side->normal.x(), -1.0, 1e-12);
  auto cap = w.raycast(ray({0.01, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(cap);
  EXPECT_NEAR(cap->t_m, 0.9, 1e-12);
  EXPECT_NEAR(cap->normal.z(), -1.0, 1e-12);
  // Above the cylinder's length: miss.
  EXPECT_FALSE(w.raycast(ray({-1, 0, 1.2}, {1, 0, 0})));
}

TEST(World, RodBetweenEndPoints) {
  World w;
  w.add({"pedicel", RodShape{{-0.1, 0, 0.5}, {0.1, 0, 0.5}, 0.003}, Eigen::Isometry3d::Identity(), paper(w)});
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->t_m, 0.497, 1e-9);
  EXPECT_FALSE(w.raycast(ray({0.11, 0, 0}, {0, 0, 1})));
  EXPECT_FALSE(w.raycast(ray({0, 0.0031, 0}, {0, 0, 1})));
}

TEST(World, MeshTriangle) {
  World w;
  MeshShape m;
  m.vertices = {{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  w.add({"tri", m, at(0, 0, 2), paper(w)});
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->t_m, 2.0, 1e-12);
  EXPECT_FALSE(w.raycast(ray({0.9, 0.9, 0}, {0, 0, 1})));
}

TEST(World, NearestOfManyAndOcclusion) {
  World w;
  for (int i = 5; i >= 1; --i) w.add({"s" + std::to_string(i), SphereShape{0.05}, at(0, 0, i), paper(w)});
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_EQ(w.object(h->object).name, "s1");
  EXPECT_TRUE(w.occluded({0, 0, 0}, {0, 0, 3}));
  EXPECT_FALSE(w.occluded({0.2, 0, 0}, {0.2, 0, 3}));
  // t_max excludes farther hits.
  EXPECT_FALSE(w.raycast(ray({0, 0, 0}, {0, 0, 1}), 1e-9, 0.9));
}

TEST(World, SetPoseMovesObject) {
  World w;
  const ObjectId id = w.add({"ball", SphereShape{0.1}, at(0, 0, 1), paper(w)});
  w.set_pose(id, at(0, 0, 2));
  const auto h = w.raycast(ray({0, 0, 0}, {0, 0, 1}));
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->t_m, 1.9, 1e-12);
}

TEST(World, RejectsDegenerateShapes) {
  World w;
  EXPECT_THROW(w.add({"bad", SphereShape{-0.1}, at(0, 0, 1), paper(w)}), std::invalid_argument);
  EXPECT_THROW(w.add({"bad", SphereShape{std::nan("")}, at(0, 0, 1), paper(w)}), std::invalid_argument);
  EXPECT_THROW(w.add({"bad", BoxShape{{0.1, 0, 0.1}}, at(0, 0, 1), paper(w)}), std::invalid_argument);
  EXPECT_THROW(w.add({"bad", RodShape{{0, 0, 0}, {0, 0, 0}, 0.01}, at(0, 0, 1), paper(w)}), std::invalid_argument);
  MeshShape m;
  m.vertices = {{0, 0, 0}};
  m.triangles = {{0, 1, 2}};
  EXPECT_THROW(w.add({"bad", m, at(0, 0, 1), paper(w)}), std::invalid_argument);
  EXPECT_THROW(w.add({"bad", SphereShape{0.1}, at(0, 0, 1), 999}), std::invalid_argument);
  try {
    w.add({"named_thing", SphereShape{0.0}, at(0, 0, 1), paper(w)});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("named_thing"), std::string::npos);
  }
}

TEST(Materials, TableFiguresSetEffectiveAlbedo) {
  const auto lib = MaterialLibrary::builtin();
  const auto& paper = lib.get(*lib.find("white_paper"));
  EXPECT_NEAR(paper.effective_albedo(), kWhitePaperAlbedo, 1e-12);
  for (const char* name : {"black_cushion", "metal_pan", "cloth_bag", "styrofoam", "white_towel", "cardboard",
                           "metal_wrench", "ic_foam"}) {
    const auto id = lib.find(name);
    ASSERT_TRUE(id) << name;
    const auto& m = lib.get(*id);
    EXPECT_NEAR(m.effective_albedo() / paper.effective_albedo(), m.reflectance_figure / kWhitePaperFigure, 1e-9)
        << name;
  }
}

TEST(Materials, MetalLobeFallsOffWithTilt) {
  const auto lib = MaterialLibrary::builtin();
  const auto& wrench = lib.get(*lib.find("metal_wrench"));
  const Eigen::Vector3d n(0, 0, -1), view(0, 0, -1);
  const double head_on = wrench.return_factor(n, view, view);
  const Eigen::Vector3d tilted = Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitY()) * view;
  const double off = wrench.return_factor(n, tilted, tilted);
  EXPECT_NEAR(head_on, wrench.effective_albedo(), 1e-9);
  EXPECT_LT(off, 0.2 * head_on);  // a 10 degree tilt loses most of the lobe
  EXPECT_GE(off, wrench.albedo);  // the diffuse part remains
}
