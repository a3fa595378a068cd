// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <pcl/point_types.h>
#include <pcl/sample_consensus/sac_model_sphere.h>

#include "synthetic.hpp"
#include "tomato_reasoning/sphere_ransac.hpp"

using namespace tinyline::tomato_reasoning;

TEST(SphereHypotheses, FourPointsGiveTheSphereAndCoplanarOnesNone) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int t = 0; t < 200; ++t) {
    const Sphere s{{u(rng), u(rng), 1 + u(rng)}, 0.02 + 0.03 * (u(rng) + 1)};
    Eigen::Vector3d p[4];
    for (auto& q : p) q = s.centre + s.radius_m * Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const auto r = sphere_from_four_points(p[0], p[1], p[2], p[3]);
    if (!r) continue;  // a rare near-coplanar draw
    EXPECT_NEAR((r->centre - s.centre).norm(), 0.0, 1e-7);
    EXPECT_NEAR(r->radius_m, s.radius_m, 1e-7);
  }
  // Coplanar (z = 0.5 plane) and collinear samples are degenerate.
  EXPECT_FALSE(sphere_from_four_points({0, 0, 0.5}, {0.1, 0, 0.5}, {0, 0.1, 0.5}, {0.1, 0.1, 0.5}));
  EXPECT_FALSE(sphere_from_four_points({0, 0, 0.5}, {0.1, 0, 0.5}, {0.2, 0, 0.5}, {0.3, 0, 0.5}));
  EXPECT_FALSE(sphere_from_four_points({0, 0, 0.5}, {0, 0, 0.5}, {0, 0.1, 0.5}, {0.1, 0.1, 0.6}));
}

TEST(SphereHypotheses, TwoPointsWithNormalsMeetAtTheCentre) {
  const Sphere s{{0.1, -0.05, 0.6}, 0.035};
  const Eigen::Vector3d n1 = Eigen::Vector3d(0.3, 0.2, -1).normalized(),
                        n2 = Eigen::Vector3d(-0.4, 0.1, -1).normalized();
  const auto r = sphere_from_two_points_with_normals(s.centre + s.radius_m * n1, n1, s.centre + s.radius_m * n2, n2);
  ASSERT_TRUE(r);
  EXPECT_NEAR((r->centre - s.centre).norm(), 0.0, 1e-12);
  EXPECT_NEAR(r->radius_m, s.radius_m, 1e-12);
  EXPECT_FALSE(sphere_from_two_points_with_normals({0, 0, 0.5}, n1, {0.01, 0, 0.5}, n1));  // parallel normals
}

TEST(SphereRefinement, GeometricFitStaysInsideTheRadiusRangeWherePclLeavesIt) {
  // A cap of a 46 mm sphere: bigger than any tomato the range allows.
  std::mt19937 rng(7);
  const Sphere truth{{0, 0, 0.5}, 0.046};
  std::vector<Eigen::Vector3f> pts;
  test::add_cap(pts, nullptr, truth, 800, 0.001, rng);
  Indices all(pts.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = int(k);
  const Sphere start{{0, 0, 0.49}, 0.038};
  const SphereRefinement ours = refine_sphere(pts, all, start, 0.025, 0.040);
  EXPECT_TRUE(ours.radius_at_limit);
  EXPECT_DOUBLE_EQ(ours.sphere.radius_m, 0.040);

  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : pts) cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  pcl::SampleConsensusModelSphere<pcl::PointXYZ> model(cloud);
  model.setRadiusLimits(0.025, 0.040);
  Eigen::VectorXf coeffs(4), refined;
  coeffs << 0, 0, 0.49f, 0.038f;
  pcl::Indices inliers(all.begin(), all.end());
  model.optimizeModelCoefficients(inliers, coeffs, refined);
  EXPECT_GT(refined[3], 0.040) << "PCL's refinement kept the radius inside the range this time";
  EXPECT_NEAR(refined[3], 0.046, 0.002);

  // Inside the range, the fit is the free least-squares optimum.
  std::vector<Eigen::Vector3f> ok;
  test::add_cap(ok, nullptr, Sphere{{0.01, 0.02, 0.45}, 0.031}, 800, 0.001, rng);
  Indices all2(ok.size());
  for (std::size_t k = 0; k < all2.size(); ++k) all2[k] = int(k);
  const SphereRefinement in = refine_sphere(ok, all2, Sphere{{0, 0.02, 0.44}, 0.028}, 0.025, 0.040);
  EXPECT_FALSE(in.radius_at_limit);
  EXPECT_TRUE(in.converged);
  EXPECT_NEAR(in.sphere.radius_m, 0.031, 0.001);
  EXPECT_NEAR((in.sphere.centre - Eigen::Vector3d(0.01, 0.02, 0.45)).norm(), 0.0, 0.0015);
}

namespace {
struct Scene {
  std::vector<Eigen::Vector3f> pts, normals;
  std::vector<Sphere> truth;
};
Scene cluster_of_caps(std::uint32_t seed) {
  std::mt19937 rng(seed);
  Scene s;
  s.truth = {{{-0.07, 0.0, 0.50}, 0.032},
             {{0.0, 0.01, 0.52}, 0.036},
             {{0.07, -0.01, 0.49}, 0.028},
             {{-0.035, 0.065, 0.51}, 0.030},
             {{0.04, 0.07, 0.50}, 0.026}};
  for (const auto& t : s.truth) test::add_cap(s.pts, &s.normals, t, 350, 0.001, rng);
  return s;
}
}  // namespace

TEST(SphereSegmentation, FindsEveryTomatoOfACluster) {
  for (SphereHypothesis h : {SphereHypothesis::kFourPoints, SphereHypothesis::kTwoPointsWithNormals}) {
    const Scene s = cluster_of_caps(11);
    SphereRansacParams p;
    p.hypothesis = h;
    const SphereSegmentation seg = segment_spheres(s.pts, s.normals, p);
    ASSERT_EQ(seg.spheres.size(), s.truth.size()) << to_string(h) << ": " << seg.stop_reason;
    for (const auto& t : s.truth) {
      double best = 1;
      for (const auto& f : seg.spheres) best = std::min(best, (f.sphere.centre - t.centre).norm());
      EXPECT_LT(best, 0.002) << to_string(h);
    }
    for (const auto& f : seg.spheres) {
      EXPECT_GT(f.cap_facing, 0.5);
      EXPECT_GE(f.sphere.radius_m, p.radius_min_m);
      EXPECT_LE(f.sphere.radius_m, p.radius_max_m);
    }
  }
}

TEST(SphereSegmentation, RefusesCapsFacingAwayFromTheCamera) {
  std::mt19937 rng(5);
  std::vector<Eigen::Vector3f> pts, radial;
  // The far side of a sphere from a camera at the origin (as if seen from behind).
  test::add_cap(pts, &radial, Sphere{{0, 0, 0.5}, 0.03}, 400, 0.0005, rng, Eigen::Vector3d(0, 0, 1.0));
  std::vector<Eigen::Vector3f> towards_origin;
  for (const auto& n : radial) towards_origin.push_back(-n);
  for (SphereHypothesis h : {SphereHypothesis::kFourPoints, SphereHypothesis::kTwoPointsWithNormals}) {
    SphereRansacParams p;
    p.hypothesis = h;
    EXPECT_TRUE(segment_spheres(pts, towards_origin, p).spheres.empty()) << to_string(h);
    // A second camera behind the fruit sees that cap: then it is a tomato.
    const auto seg = segment_spheres(pts, radial, p, std::vector<Eigen::Vector3f>{{0, 0, 0}, {0, 0, 1.0f}});
    EXPECT_EQ(seg.spheres.size(), 1u) << to_string(h) << ": " << seg.stop_reason;
  }
  // Four points and no normals at all: only the cap test stands in the way.
  SphereRansacParams bare;
  bare.hypothesis = SphereHypothesis::kFourPoints;
  bare.normal_tolerance_deg = 0;
  const auto seg = segment_spheres(pts, {}, bare);
  EXPECT_TRUE(seg.spheres.empty());
  EXPECT_GT(seg.rejected_cap, 0);
  EXPECT_EQ(segment_spheres(pts, {}, bare, std::vector<Eigen::Vector3f>{{0, 0, 1.0f}}).spheres.size(), 1u);
}

TEST(SphereSegmentation, SameSeedSameSpheres) {
  const Scene s = cluster_of_caps(12);
  const auto a = segment_spheres(s.pts, s.normals), b = segment_spheres(s.pts, s.normals);
  ASSERT_EQ(a.spheres.size(), b.spheres.size());
  for (std::size_t k = 0; k < a.spheres.size(); ++k) EXPECT_EQ(a.spheres[k].sphere.centre, b.spheres[k].sphere.centre);
}

TEST(SphereSegmentation, DegenerateInputGivesNoSphereAndTheReason) {
  // A flat red patch (a coplanar sample everywhere): no sphere fits it.
  std::vector<Eigen::Vector3f> plane, up;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) {
      plane.emplace_back(0.002f * i, 0.002f * j, 0.5f);
      up.emplace_back(0, 0, -1);
    }
  SphereRansacParams four;
  four.hypothesis = SphereHypothesis::kFourPoints;
  const auto flat = segment_spheres(plane, up, four);
  EXPECT_TRUE(flat.spheres.empty());
  EXPECT_GT(flat.degenerate, 0);
  EXPECT_FALSE(flat.stop_reason.empty());
  EXPECT_TRUE(segment_spheres(plane, up).spheres.empty());

  EXPECT_EQ(segment_spheres({}, {}).status.message, "no points");
  EXPECT_EQ(segment_spheres({}, {}).status.code, tinyline::common::StatusCode::NotFound);
  std::vector<Eigen::Vector3f> one{{0, 0, 0.5f}}, n1{{0, 0, -1}};
  EXPECT_NE(segment_spheres(one, n1).status.message.find("usable points"), std::string::npos);
  EXPECT_NE(segment_spheres(plane, {}).status.message.find("normals are needed"), std::string::npos);
  std::vector<Eigen::Vector3f> nan(100, Eigen::Vector3f(NAN, NAN, NAN));
  EXPECT_TRUE(segment_spheres(nan, nan).spheres.empty());
  SphereRansacParams bad;
  bad.radius_min_m = 0.05;
  EXPECT_NE(segment_spheres(plane, up, bad).status.message.find("radius range"), std::string::npos);
}
