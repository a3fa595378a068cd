// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>

#include <sim/config_error.hpp>
#include <sim/scene.hpp>
#include <sim/scenes/truss.hpp>

using namespace tinyline::sim;

namespace {

std::string src(const std::string& rel) { return std::string(TINYLINE_SOURCE_DIR) + "/" + rel; }

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

TrussParams params(TrussClass c, std::uint64_t seed) {
  TrussParams p;
  p.complexity = c;
  p.seed = seed;
  return p;
}

}  // namespace

TEST(Truss, EveryClassSettlesWithoutOverlapAndKeepsItsGeometry) {
  for (TrussClass c : {TrussClass::kA, TrussClass::kB, TrussClass::kC}) {
    for (std::uint64_t seed = 1; seed <= 15; ++seed) {
      const Truss t = make_truss(params(c, seed));
      SCOPED_TRACE(std::string("class ") + static_cast<char>(c) + " seed " + std::to_string(seed));
      ASSERT_TRUE(t.relaxation.converged) << "residual " << t.relaxation.max_torque_residual;
      const int n = static_cast<int>(t.tomatoes.size());
      switch (c) {
        case TrussClass::kA: EXPECT_TRUE(n >= 1 && n <= 2); break;
        case TrussClass::kB: EXPECT_TRUE(n >= 3 && n <= 4); break;
        case TrussClass::kC: EXPECT_TRUE(n >= 5 && n <= 8); break;
      }
      for (int i = 0; i < n; ++i) {
        const auto& a = t.tomatoes[std::size_t(i)];
        EXPECT_GE(a.radius_m, 0.025);
        EXPECT_LE(a.radius_m, 0.040);
        EXPECT_NEAR(a.pedicel_dir.norm(), 1.0, 1e-12);
        // The centre lies on the pedicel line, pedicel length + polar radius from the anchor.
        const double arm = (a.anchor_m - a.centre_m).norm();
        EXPECT_NEAR((a.anchor_m - a.calyx_m).norm() + a.polar_radius_m, arm, 1e-9);
        // An oblate fruit of the drawn volume.
        EXPECT_NEAR(std::cbrt(a.equatorial_radius_m * a.equatorial_radius_m * a.polar_radius_m), a.radius_m, 1e-9);
        EXPECT_LE(a.polar_radius_m, a.equatorial_radius_m);
        EXPECT_GE(a.polar_radius_m, 0.82 * a.equatorial_radius_m - 1e-9);
        EXPECT_LT(angle_deg(a.anchor_m - a.centre_m, a.pedicel_dir), 1e-4);
        // Hanging: the pedicel leaves the fruit upwards, or at least not steeply down.
        EXPECT_GT(a.pedicel_dir.z(), -0.5);
        for (int j = i + 1; j < n; ++j) {
          const auto& b = t.tomatoes[std::size_t(j)];
          EXPECT_GE((a.centre_m - b.centre_m).norm(), a.bounding_radius_m + b.bounding_radius_m - 1e-4)
              << i << " overlaps " << j;
        }
      }
      if (c == TrussClass::kA) {
        EXPECT_TRUE(t.contacts.empty());
      }
      for (const auto& k : t.contacts) EXPECT_GT(k.force_n, 0.0);
    }
  }
}

TEST(Truss, DenseClassesTouchAndSimpleOnesDoNot) {
  int contacts_b = 0, contacts_c = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    contacts_b += static_cast<int>(make_truss(params(TrussClass::kB, seed)).contacts.size());
    contacts_c += static_cast<int>(make_truss(params(TrussClass::kC, seed)).contacts.size());
  }
  EXPECT_GT(contacts_b, 5);
  EXPECT_GT(contacts_c, 2 * contacts_b);
}

// With limp pedicels (no bending stiffness) the pedicel can only pull along
// itself: torque balance about the anchor makes the pedicel force parallel
// to the pedicel, and a fruit that touches nothing hangs plumb. This checks
// the relaxation's rest state and its contact forces against statics they
// were not computed from.
TEST(Truss, LimpPedicelsPullAlongThemselves) {
  int checked = 0;
  for (TrussClass c : {TrussClass::kA, TrussClass::kB, TrussClass::kC}) {
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
      TrussParams p = params(c, seed);
      p.stiffness_ratio_min = p.stiffness_ratio_max = 0.0;
      const Truss t = make_truss(p);
      ASSERT_TRUE(t.relaxation.converged);
      for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
        const auto& a = t.tomatoes[i];
        bool touches = false;
        for (const auto& k : t.contacts) touches = touches || k.i == int(i) || k.j == int(i);
        if (!touches) {
          EXPECT_LT(angle_deg(a.pedicel_dir, Eigen::Vector3d::UnitZ()), 0.05);
        }
        EXPECT_LT(angle_deg(a.pedicel_force_n, a.pedicel_dir), 0.5) << "class " << char(c) << " seed " << seed;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 80);
}

// Newton's third law across the truss: when fruit touch only fruit (not
// the peduncle or another's pedicel), the pedicels together carry exactly
// the fruit's weight; contacts only move load between them.
TEST(Truss, PedicelsCarryTheWholeWeight) {
  int checked = 0;
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    const Truss t = make_truss(params(TrussClass::kC, seed));
    bool other = false;
    for (const auto& k : t.contacts) other = other || k.kind != ContactKind::kFruit;
    if (other) continue;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight = 0;
    for (const auto& a : t.tomatoes) {
      sum += a.pedicel_force_n;
      weight += a.mass_kg * 9.81;
    }
    EXPECT_NEAR(sum.z(), weight, 0.02 * weight);
    EXPECT_NEAR(sum.head<2>().norm(), 0.0, 0.02 * weight);
    ++checked;
  }
  EXPECT_GT(checked, 5);
}

TEST(Truss, SameSeedSameTrussOtherSeedOtherTruss) {
  const Truss a = make_truss(params(TrussClass::kB, 42));
  const Truss b = make_truss(params(TrussClass::kB, 42));
  const Truss c = make_truss(params(TrussClass::kB, 43));
  ASSERT_EQ(a.tomatoes.size(), b.tomatoes.size());
  for (std::size_t i = 0; i < a.tomatoes.size(); ++i) EXPECT_EQ(a.tomatoes[i].centre_m, b.tomatoes[i].centre_m);
  EXPECT_TRUE(a.tomatoes.size() != c.tomatoes.size() || a.tomatoes[0].centre_m != c.tomatoes[0].centre_m);
}

TEST(Truss, CameraLooksAtTheFruitFromTheHandCameraRange) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const Truss t = make_truss(params(TrussClass::kC, seed));
    const Eigen::Isometry3d T_cam_world = t.T_world_camera.inverse();
    for (const auto& a : t.tomatoes) {
      const Eigen::Vector3d p = T_cam_world * a.centre_m;
      EXPECT_GT(p.z(), 0.30);  // the thesis's hand-camera range [0.35, 0.6] m, minus the fruit's depth
      EXPECT_LT(p.z(), 0.65);
      EXPECT_LT(std::abs(p.x() / p.z()), std::tan(29.0 * M_PI / 180.0));  // inside the 58 deg field of view
    }
  }
}

TEST(Truss, SceneFilesLoadWithTruth) {
  for (const char* f : {"truss_a.yaml", "truss_b.yaml", "truss_c.yaml"}) {
    const Scene s = load_scene(src(std::string("sim/config/scenes/") + f));
    const TrussTruth truth = truss_truth_from_scene(s);
    ASSERT_FALSE(truth.tomatoes.empty()) << f;
    EXPECT_EQ(truth.seed, 1u);
    // The truth matches the world: from each centre, the first surface in
    // any direction is that fruit's skin, between its polar and equatorial radii.
    for (const auto& t : truth.tomatoes) {
      const Eigen::Vector3d dirs[] = {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, -1, 0),
                                      Eigen::Vector3d(0.3, 0.2, -1).normalized()};
      for (const Eigen::Vector3d& dir : dirs) {
        const auto hit = s.world.raycast({t.centre_m, dir});
        ASSERT_TRUE(hit);
        EXPECT_NE(s.world.object(hit->object).name.find("tomato"), std::string::npos);
        EXPECT_GE(hit->t_m, 0.99 * t.polar_radius_m);
        EXPECT_LE(hit->t_m, 1.04 * t.equatorial_radius_m);
      }
    }
  }
  const Scene b = load_scene(src("sim/config/scenes/truss_b.yaml"));
  EXPECT_EQ(truss_truth_from_scene(b).complexity, TrussClass::kB);
}

TEST(Truss, TruthRoundTripsThroughTheScene) {
  const Truss t = make_truss(params(TrussClass::kC, 7));
  Scene s;
  write_truth(t, s);
  const TrussTruth r = truss_truth_from_scene(s);
  ASSERT_EQ(r.tomatoes.size(), t.tomatoes.size());
  for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
    EXPECT_EQ(r.tomatoes[i].centre_m, t.tomatoes[i].centre_m);
    EXPECT_EQ(r.tomatoes[i].pedicel_dir, t.tomatoes[i].pedicel_dir);
  }
  EXPECT_EQ(r.contacts.size(), t.contacts.size());
  EXPECT_TRUE(r.T_world_camera.isApprox(t.T_world_camera, 1e-12));
  EXPECT_EQ(r.complexity, TrussClass::kC);
  EXPECT_EQ(r.seed, 7u);
}

TEST(Truss, BadInputIsRefusedWithTheReason) {
  TrussParams p;
  p.num_tomatoes = 9;
  EXPECT_THROW((void)make_truss(p), std::invalid_argument);
  p = {};
  p.radius_min_m = 0.05;  // above the max
  EXPECT_THROW((void)make_truss(p), std::invalid_argument);
  p = {};
  p.origin_m.x() = NAN;
  EXPECT_THROW((void)make_truss(p), std::invalid_argument);

  auto expect_config_error = [](const std::string& yaml, const std::string& fragment) {
    try {
      (void)load_scene_string(yaml, "t.yaml", ".");
      FAIL() << "accepted:\n" << yaml;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
      EXPECT_EQ(e.line(), 3) << e.what();
    }
  };
  expect_config_error("name: x\ngenerators:\n  - {type: truss, class: D}\n", "class must be A, B or C");
  expect_config_error("name: x\ngenerators:\n  - {type: truss, clas: A}\n", "clas");
  expect_config_error("name: x\ngenerators:\n  - {type: truss, num_tomatoes: 12}\n", "num_tomatoes");
  Scene empty;
  EXPECT_THROW((void)truss_truth_from_scene(empty), std::runtime_error);
}
