// SPDX-License-Identifier: Apache-2.0
// The evaluation's scenes: their geometry and ground truth, by ray casting.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "scenes.hpp"

namespace ev = tinyline::laser_clustering::eval;
namespace sim = tinyline::sim;

namespace {
sim::Ray ray_to(const Eigen::Isometry3d& T_world_sensor, const Eigen::Vector3d& p_sensor) {
  sim::Ray r;
  r.origin = T_world_sensor.translation();
  r.dir = (T_world_sensor * p_sensor - r.origin).normalized();
  return r;
}
}  // namespace

TEST(EvalScenes, TrussTargetIsWhereTheTruthSaysAndTomatoesDoNotOverlap) {
  for (const auto c : {ev::TrussCase::kRandomOffset, ev::TrussCase::kRecognitionError}) {
    int hits = 0, neighbours = 0;
    for (std::uint64_t seed = 0; seed < 200; ++seed) {
      const auto s = ev::make_truss_scene(c, seed);
      const auto& t = s.truth;
      ASSERT_GE(t.pedicels.size(), 2u);
      neighbours += static_cast<int>(t.pedicels.size()) - 1;
      EXPECT_NEAR(t.target_in_sensor.y(), 0.0, 1e-9) << "on the laser plane";
      const auto h = s.world.raycast(ray_to(s.T_world_sensor, t.target_in_sensor));
      hits += h && h->object == t.target_pedicel;
      for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
        for (std::size_t j = i + 1; j < t.tomatoes.size(); ++j) {
          const auto& a = s.world.object(t.tomatoes[i]);
          const auto& b = s.world.object(t.tomatoes[j]);
          const double ra = std::get<sim::SphereShape>(a.shape).radius_m,
                       rb = std::get<sim::SphereShape>(b.shape).radius_m;
          EXPECT_GT((a.T_world_object.translation() - b.T_world_object.translation()).norm(), ra + rb);
        }
      }
      if (c == ev::TrussCase::kRandomOffset) {
        EXPECT_LE(std::hypot(t.target_in_sensor.x(), t.target_in_sensor.z() - 0.15), 0.05 + 1e-9);
      }
    }
    // Only a neighbour in front of it hides the target's axis from the laser.
    EXPECT_GE(hits, 180) << "case " << static_cast<int>(c);
    EXPECT_GE(neighbours, 250);
  }
}

TEST(EvalScenes, SameSeedSameScene) {
  const auto a = ev::make_truss_scene(ev::TrussCase::kRecognitionError, 42);
  const auto b = ev::make_truss_scene(ev::TrussCase::kRecognitionError, 42);
  ASSERT_EQ(a.world.size(), b.world.size());
  EXPECT_TRUE(a.T_world_sensor.isApprox(b.T_world_sensor));
  EXPECT_TRUE(a.truth.target_in_sensor.isApprox(b.truth.target_in_sensor));
}

TEST(EvalScenes, StickStandsTheGapBeforeThePanel) {
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    ev::StickOptions o;
    o.front_gap_m = 0.005;
    const auto s = ev::make_stick_scene(seed, o);
    const Eigen::Vector3d c = s.world.object(s.stick).T_world_object.translation();
    const auto on = s.world.raycast(ray_to(s.T_world_sensor, c));
    ASSERT_TRUE(on);
    EXPECT_EQ(on->object, s.stick);
    // Beside the stick, the panel; about the gap further.
    const auto off = s.world.raycast(ray_to(s.T_world_sensor, c + Eigen::Vector3d(0.02, 0.0, 0.0)));
    ASSERT_TRUE(off);
    EXPECT_EQ(off->object, s.panel);
    EXPECT_NEAR(off->point.z() - on->point.z(), 0.005, 0.0025);
  }
}

TEST(EvalScenes, WrenchTruePitchSquaresTheOpticalAxisToTheFace) {
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    const auto s = ev::make_wrench_scene(seed);
    const Eigen::Vector3d m = s.world.object(s.wrench).T_world_object.linear().col(2);
    // The pitch that minimises the angle between the optical axis and the face normal.
    double best = 0.0, best_angle = 10.0;
    for (double p = -0.3; p <= 0.3; p += 1e-4) {
      const Eigen::Vector3d axis = s.T_world_sensor(p).linear().col(2);
      const double angle = std::acos(std::min(1.0, std::abs(axis.dot(m))));
      if (angle < best_angle) {
        best_angle = angle;
        best = p;
      }
    }
    EXPECT_NEAR(best, s.true_pitch_rad, 2e-4);
    // At that pitch the laser still hits the wrench on its axis.
    const auto T = s.T_world_sensor(s.true_pitch_rad);
    sim::Ray r;
    r.origin = T.translation();
    r.dir = T.linear().col(2);
    const auto h = s.world.raycast(r);
    ASSERT_TRUE(h);
    const double x = s.world.object(s.wrench).T_world_object.translation().x();
    if (std::abs(x) < 0.009) {
      EXPECT_EQ(h->object, s.wrench);
    }
  }
}

TEST(EvalScenes, WiderTiltsAndACurvedStemAreSceneOptions) {
  ev::TrussOptions o;
  EXPECT_EQ(ev::set_truss_option(o, "max_tilt_deg", "30"), "");
  EXPECT_EQ(ev::set_truss_option(o, "stem_bow_m", "0.03"), "");
  EXPECT_NE(ev::set_truss_option(o, "max_tilt_deg", "75"), "");
  EXPECT_NE(ev::set_truss_option(o, "stem_bow_m", "x"), "");
  EXPECT_NE(ev::set_truss_option(o, "wobble", "1"), "");
  ev::TrussOptions tilted;
  tilted.max_tilt_deg = 30.0;
  double widest = 0.0;
  int matched = 0;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    const auto bowed = ev::make_truss_scene(ev::TrussCase::kRandomOffset, seed, o);
    const auto straight = ev::make_truss_scene(ev::TrussCase::kRandomOffset, seed, tilted);
    auto top = [](const ev::TrussScene& s, std::size_t i) {
      return std::get<sim::RodShape>(s.world.object(s.truth.pedicels[i]).shape).p0;
    };
    for (auto id : bowed.truth.pedicels) {
      const auto& rod = std::get<sim::RodShape>(bowed.world.object(id).shape);
      const Eigen::Vector3d d = (rod.p1 - rod.p0).normalized();
      widest = std::max(widest, std::acos(std::clamp(d.y(), -1.0, 1.0)) * 180.0 / M_PI);
    }
    // Same draws: each neighbour's top moved across the stem by the bow at its distance.
    if (bowed.truth.pedicels.size() != straight.truth.pedicels.size()) continue;
    for (std::size_t i = 1; i < bowed.truth.pedicels.size(); ++i) {
      const Eigen::Vector3d moved = top(bowed, i) - top(straight, i);
      const double dx = top(straight, i).x() - top(straight, 0).x();
      if (std::abs(moved.x()) > 1e-12) continue;  // a redrawn neighbour
      EXPECT_NEAR(moved.norm(), 0.03 * (dx / 0.1) * (dx / 0.1), 1e-9);
      ++matched;
    }
  }
  EXPECT_GT(widest, 20.0);
  EXPECT_LE(widest, 30.0 + 1e-9);
  EXPECT_GT(matched, 20);
}
