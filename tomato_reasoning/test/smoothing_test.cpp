// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "synthetic.hpp"
#include "tomato_reasoning/smoothing.hpp"

using namespace tinyline::tomato_reasoning;

namespace {
double rms_to_sphere(const std::vector<Eigen::Vector3f>& pts, const Sphere& s) {
  double e = 0;
  for (const auto& p : pts) e += std::pow((p.cast<double>() - s.centre).norm() - s.radius_m, 2);
  return std::sqrt(e / pts.size());
}
Indices all_of(std::size_t n) {
  Indices i(n);
  for (std::size_t k = 0; k < n; ++k) i[k] = int(k);
  return i;
}
}  // namespace

TEST(Smoothing, MlsPullsANoisyCapOntoItsSphereWithRadialNormals) {
  std::mt19937 rng(3);
  const Sphere s{{0.02, -0.01, 0.5}, 0.03};
  std::vector<Eigen::Vector3f> pts;
  test::add_cap(pts, nullptr, s, 6000, 0.001, rng);  // 1 mm: the depth noise at 0.7 m
  const SmoothedCloud out = smooth_mls(pts, all_of(pts.size()));
  ASSERT_GT(out.size(), 500u);
  const double before = rms_to_sphere(pts, s), after = rms_to_sphere(out.points, s);
  EXPECT_LT(after, before / 2.5) << "before " << before << " after " << after;
  std::vector<double> err;
  int facing = 0;
  for (std::size_t k = 0; k < out.size(); ++k) {
    const Eigen::Vector3d radial = (out.points[k].cast<double>() - s.centre).normalized();
    err.push_back(std::acos(std::clamp(radial.dot(out.normals[k].cast<double>()), -1.0, 1.0)) * 180 / M_PI);
    facing += out.normals[k].dot(-out.points[k]) > 0;  // towards the camera at the origin
  }
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[err.size() / 2], 3.0);        // median
  EXPECT_LT(err[err.size() * 9 / 10], 12.0);  // the cap's rim has one-sided neighbourhoods
  EXPECT_EQ(facing, int(out.size()));
}

TEST(Smoothing, QuadraticFitBeatsThePlaneOnACurvedSurface) {
  std::mt19937 rng(4);
  const Sphere s{{0, 0, 0.45}, 0.026};
  std::vector<Eigen::Vector3f> pts;
  test::add_cap(pts, nullptr, s, 5000, 0.0005, rng);
  SmoothingParams plane;
  plane.polynomial_order = 1;
  const double quad_err = rms_to_sphere(smooth_mls(pts, all_of(pts.size())).points, s);
  const double plane_err = rms_to_sphere(smooth_mls(pts, all_of(pts.size()), plane).points, s);
  EXPECT_LT(quad_err, 0.5 * plane_err);  // the plane pulls points inside, by the sagitta
}

TEST(Smoothing, VoxelThinningKeepsOneCentroidPerCube) {
  std::vector<Eigen::Vector3f> pts{
      {0.0001f, 0.0001f, 0.5001f}, {0.0009f, 0.0009f, 0.5009f}, {0.05f, 0, 0.5f}, {NAN, 0, 0}};
  const auto thin = voxel_thin(pts, all_of(pts.size()), 0.002);
  ASSERT_EQ(thin.size(), 2u);
  EXPECT_NEAR(thin[0].x(), 0.0005, 1e-6);
}

TEST(Smoothing, EachNormalFacesTheViewThatSawIt) {
  // A thin slab seen from both sides: points from view 0 (at z = 0) and
  // view 1 (at z = 1) lie on the same plane z = 0.5, in different voxels.
  std::vector<Eigen::Vector3f> pts;
  std::vector<std::uint8_t> view;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) {
      pts.emplace_back(0.002f * i, 0.002f * j, 0.5f);
      view.push_back(i < 20 ? 0 : 1);
    }
  const std::vector<Eigen::Vector3f> eyes{{0.04f, 0.04f, 0.0f}, {0.04f, 0.04f, 1.0f}};
  SmoothingParams p;
  p.voxel_m = 0;
  const SmoothedCloud out = smooth_mls(pts, all_of(pts.size()), p, eyes, view);
  ASSERT_EQ(out.size(), pts.size());
  for (std::size_t k = 0; k < out.size(); ++k) EXPECT_EQ(out.normals[k].z() < 0, view[k] == 0) << k;
}

TEST(Smoothing, BadInputGivesAnEmptyResultWithTheReason) {
  std::vector<Eigen::Vector3f> pts{{0, 0, 0.5f}};
  EXPECT_EQ(smooth_mls(pts, {}).status.message, "no points to smooth");
  const SmoothedCloud one = smooth_mls(pts, {0});
  EXPECT_TRUE(one.points.empty());
  EXPECT_EQ(one.dropped_isolated, 1);
  EXPECT_NE(one.status.message.find("isolated"), std::string::npos);
  std::vector<Eigen::Vector3f> nan{{NAN, 0, 0}, {0, NAN, 0}};
  EXPECT_EQ(smooth_mls(nan, {0, 1}).status.message, "no finite points to smooth");
  EXPECT_NE(smooth_mls(pts, {3}).status.message.find("outside"), std::string::npos);
  SmoothingParams bad;
  bad.polynomial_order = 3;
  EXPECT_NE(smooth_mls(pts, {0}, bad).status.message.find("polynomial_order"), std::string::npos);
  EXPECT_NE(smooth_mls(pts, {0}, {}, {Eigen::Vector3f::Zero()}, {}).status.message.find("view_of"), std::string::npos);
}
