// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include <sim/rgbd_camera.hpp>
#include <sim/scenes/truss.hpp>

using namespace tinyline::sim;

namespace {

// Hue, saturation and intensity as PCL's PackedHSIComparison defines them
// (the filter thesis 4.3.1 used), hue in degrees.
struct Hsi {
  double h_deg, s, i;
};
Hsi hsi(const std::array<std::uint8_t, 3>& c) {
  const double r = c[0], g = c[1], b = c[2];
  const double hx = (2 * r - g - b) / 4.0, hy = (g - b) * 111.0 / 255.0;
  const double i = std::floor((r + g + b) / 3.0);
  const double m = std::min({r, g, b});
  return {std::atan2(hy, hx) * 180.0 / M_PI, i == 0 ? 0.0 : 255.0 - std::floor(m * 255.0 / i), i};
}
bool passes_thesis_filter(const std::array<std::uint8_t, 3>& c) {
  const Hsi x = hsi(c);
  return x.h_deg >= -15 && x.h_deg <= 15 && x.s >= 100 && x.s <= 250 && x.i >= 25 && x.i <= 180;
}

Object plane_at(double z, double size = 4.0, const char* material = "white_matte") {
  Object o;
  o.name = "wall";
  o.shape = PlaneShape{Eigen::Vector2d(size, size)};
  o.T_world_object.translation() = Eigen::Vector3d(0, 0, z);
  o.material = *MaterialLibrary::builtin().find(material);
  return o;
}

// Camera at the origin looking along world +z (optical frame = world frame).
const Eigen::Isometry3d kAtOrigin = Eigen::Isometry3d::Identity();

double depth_sd(const RgbdFrame& f, double truth) {
  double s = 0, s2 = 0;
  int n = 0;
  // A central window, clear of the plane's edges.
  for (int v = f.height / 2 - 60; v < f.height / 2 + 60; ++v) {
    for (int u = f.width / 2 - 80; u < f.width / 2 + 80; ++u) {
      const std::size_t i = static_cast<std::size_t>(v * f.width + u);
      if (!f.valid(i)) continue;
      const double e = f.depth_m[i] - truth;
      s += e;
      s2 += e * e;
      ++n;
    }
  }
  const double mean = s / n;
  return std::sqrt(s2 / n - mean * mean);
}

}  // namespace

TEST(RgbdCamera, DepthNoiseGrowsWithTheSquareOfRange) {
  RgbdCameraParams p;
  p.disparity_step_px = 0;  // quantisation would dominate at short range
  const RgbdCamera cam(p);
  std::vector<double> sd;
  for (double z : {0.5, 1.0, 2.0}) {
    World w;
    w.add(plane_at(z));
    const RgbdFrame f = cam.render(w, kAtOrigin, 3);
    sd.push_back(depth_sd(f, z));
    // sigma_z = z^2 sigma_d / (f b), sigma_d the two disparity noise parts together.
    const double expected = z * z * std::hypot(p.disparity_noise_px, p.disparity_noise_correlated_px) /
                            (p.intrinsics.fx * p.projector_baseline_m);
    EXPECT_NEAR(sd.back(), expected, 0.3 * expected) << "z " << z;
  }
  EXPECT_NEAR(sd[1] / sd[0], 4.0, 1.0);
  EXPECT_NEAR(sd[2] / sd[1], 4.0, 1.0);
}

TEST(RgbdCamera, DepthIsUnbiasedAndPointsProjectBack) {
  World w;
  w.add(plane_at(0.6));
  const RgbdCamera cam;
  const RgbdFrame f = cam.render(w, kAtOrigin, 0);
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.valid(i)) continue;
    sum += f.depth_m[i];
    ++n;
    const Eigen::Vector3f p = f.point(i);
    Eigen::Vector2d uv;
    ASSERT_TRUE(cam.project(p.cast<double>(), uv));
    EXPECT_NEAR(uv.x(), double(i % std::size_t(f.width)), 1e-3);
    EXPECT_NEAR(uv.y(), double(i / std::size_t(f.width)), 1e-3);
  }
  EXPECT_GT(n, 0.95 * double(f.size()));
  EXPECT_NEAR(sum / n, 0.6, 0.0005);
}

TEST(RgbdCamera, OutOfRangeHasNoDepth) {
  World w;
  w.add(plane_at(0.2));  // nearer than the 0.35 m minimum
  EXPECT_EQ(RgbdCamera().render(w, kAtOrigin).num_valid(), 0u);
  World far;
  far.add(plane_at(5.0, 40.0));
  EXPECT_EQ(RgbdCamera().render(far, kAtOrigin).num_valid(), 0u);
}

TEST(RgbdCamera, SilhouetteEdgesAndProjectorShadowLoseDepth) {
  World w;
  w.add(plane_at(1.0));
  Object rod;
  rod.name = "rod";
  rod.shape = RodShape{{0, -0.3, 0}, {0, 0.3, 0}, 0.01};  // vertical in the image
  rod.T_world_object.translation() = Eigen::Vector3d(0, 0, 0.5);
  rod.material = *w.materials().find("stem");
  w.add(rod);
  const RgbdCamera cam;
  const RgbdFrame f = cam.render(w, kAtOrigin);
  // Along the middle row: the rod spans u in [cx - 11.4, cx + 11.4] px.
  const int v = f.height / 2;
  const double cx = f.intrinsics.cx, half = f.intrinsics.fx * 0.01 / 0.5;
  int interior_missing = 0;
  for (int u = int(cx - half) + 3; u <= int(cx + half) - 3; ++u)
    interior_missing += !f.valid(std::size_t(v * f.width + u));
  EXPECT_EQ(interior_missing, 0);
  // The projector (at +x) casts the rod's shadow on the wall at
  // x in [-0.095, -0.055] m (lines from the projector past the rod's edges),
  // seen at u in [cx - 54, cx - 31] px: no depth there, while the wall on the
  // other side keeps its depth.
  int shadow_missing = 0, shadow = 0, other_missing = 0;
  for (int u = int(cx - 52); u <= int(cx - 33); ++u, ++shadow) shadow_missing += !f.valid(std::size_t(v * f.width + u));
  for (int k = 4; k < 36; ++k) other_missing += !f.valid(std::size_t(v * f.width + int(cx + half) + k));
  EXPECT_EQ(shadow_missing, shadow);
  EXPECT_LE(other_missing, 2);
  // Silhouette pixels lose depth far more often than the interior.
  int edge_missing = 0, edges = 0;
  for (int vv = 100; vv < 380; ++vv) {
    for (int u : {int(std::floor(cx - half)), int(std::floor(cx - half)) + 1}) {
      edge_missing += !f.valid(std::size_t(vv * f.width + u));
      ++edges;
    }
  }
  EXPECT_GT(edge_missing, edges / 2);
}

TEST(RgbdCamera, TomatoesPassTheThesisHsiFilterAndFoliageDoesNot) {
  int red = 0, red_pass = 0, green = 0, green_pass = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    TrussParams tp;
    tp.complexity = TrussClass::kC;
    tp.seed = seed;
    const Truss t = make_truss(tp);
    World w;
    (void)add_to_world(t, w);
    const RgbdFrame f = RgbdCamera().render(w, t.T_world_camera, seed);
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (f.object[i] == kNoObject) continue;
      const std::string& name = w.materials().get(w.object(f.object[i]).material).name;
      if (name.rfind("tomato_red", 0) == 0) {
        ++red;
        red_pass += passes_thesis_filter(f.rgb[i]);
      } else if (name == "leaf" || name == "stem") {
        ++green;
        green_pass += passes_thesis_filter(f.rgb[i]);
      }
    }
  }
  ASSERT_GT(red, 10000);
  ASSERT_GT(green, 10000);
  // Most of the skin passes; highlights and deep shade do not (as on real fruit).
  EXPECT_GT(double(red_pass) / red, 0.85);
  EXPECT_LT(double(red_pass) / red, 0.995);
  EXPECT_LT(double(green_pass) / green, 0.001);
}

TEST(RgbdCamera, TileCullingRendersTheSameFrame) {
  TrussParams tp;
  tp.complexity = TrussClass::kC;
  tp.seed = 5;
  const Truss t = make_truss(tp);
  World w;
  (void)add_to_world(t, w);
  RgbdCameraParams ref;
  ref.tile_culling = false;
  const RgbdFrame a = RgbdCamera().render(w, t.T_world_camera, 2);
  const RgbdFrame b = RgbdCamera(ref).render(w, t.T_world_camera, 2);
  ASSERT_EQ(a.size(), b.size());
  std::size_t depth_diff = 0, colour_diff = 0, object_diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    depth_diff += !(a.depth_m[i] == b.depth_m[i] || (std::isnan(a.depth_m[i]) && std::isnan(b.depth_m[i])));
    colour_diff += a.rgb[i] != b.rgb[i];
    object_diff += a.object[i] != b.object[i];
  }
  EXPECT_EQ(depth_diff, 0u);
  EXPECT_EQ(colour_diff, 0u);
  EXPECT_EQ(object_diff, 0u);
}

TEST(RgbdCamera, SameFrameIndexSameNoise) {
  World w;
  w.add(plane_at(0.8));
  const RgbdCamera cam;
  const RgbdFrame a = cam.render(w, kAtOrigin, 7), b = cam.render(w, kAtOrigin, 7), c = cam.render(w, kAtOrigin, 8);
  std::size_t same_ab = 0, same_ac = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    same_ab += a.depth_m[i] == b.depth_m[i];
    same_ac += a.depth_m[i] == c.depth_m[i];
  }
  EXPECT_EQ(same_ab, a.num_valid());
  EXPECT_LT(same_ac, a.num_valid() / 2);
}

TEST(RgbdCamera, DistortionFollowsEquation4_4) {
  RgbdCameraParams p;
  p.disparity_noise_px = p.disparity_noise_correlated_px = p.disparity_step_px = 0;
  p.distortion.spatial_m = {0.004, 0.0, 0.0, 0.02, 0.0, 0.01};
  p.distortion.z_slope = 0.01;
  World w;
  w.add(plane_at(0.5));
  const RgbdFrame f = RgbdCamera(p).render(w, kAtOrigin);
  for (const auto& [u, v] : {std::pair{320, 240}, {20, 20}, {600, 400}}) {
    const std::size_t i = std::size_t(v * f.width + u);
    ASSERT_TRUE(f.valid(i));
    const double xn = (u - p.intrinsics.cx) / p.intrinsics.width, yn = (v - p.intrinsics.cy) / p.intrinsics.height;
    EXPECT_NEAR(f.depth_m[i] - 0.5, p.distortion.offset_m(xn, yn, 0.5), 2e-6) << u << "," << v;
  }
}

TEST(RgbdCamera, BadParametersAreRefused) {
  auto bad = [](auto edit) {
    RgbdCameraParams p;
    edit(p);
    EXPECT_FALSE(p.validate().ok());
    EXPECT_THROW(RgbdCamera{p}, std::invalid_argument);
  };
  bad([](RgbdCameraParams& p) { p.intrinsics.width = 0; });
  bad([](RgbdCameraParams& p) { p.intrinsics.fx = NAN; });
  bad([](RgbdCameraParams& p) {
    p.min_depth_m = 2.0;
    p.max_depth_m = 1.0;
  });
  bad([](RgbdCameraParams& p) { p.edge_dropout = 1.5; });
  bad([](RgbdCameraParams& p) { p.correlation_window_px = 0; });
  bad([](RgbdCameraParams& p) { p.distortion.z_slope = INFINITY; });
}

TEST(RgbdCamera, LookAtPutsTheTargetOnTheOpticalAxisWithUpUp) {
  const Eigen::Isometry3d T = look_at({0, -0.5, 1.0}, {0.1, 0.0, 1.1});
  const Eigen::Vector3d t = T.inverse() * Eigen::Vector3d(0.1, 0.0, 1.1);
  EXPECT_NEAR(t.x(), 0, 1e-12);
  EXPECT_NEAR(t.y(), 0, 1e-12);
  EXPECT_GT(t.z(), 0);
  EXPECT_LT((T.linear() * Eigen::Vector3d::UnitY()).z(), 0);  // image down is world down
}
