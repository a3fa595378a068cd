// SPDX-License-Identifier: Apache-2.0
// The box-side fit (Figure 6.7 A): two perpendicular sides, one side with a
// known size, outliers, and degenerate input.
#include <cmath>
#include <numbers>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/common/random.hpp>
#include "hydrus_fitting/rectangle_fit.hpp"

namespace hf = tinyline::hydrus_fitting;

namespace {

constexpr double kPi = std::numbers::pi;

/// Points on the two sides of a box (centre c, yaw, size a x b) that face a
/// viewer at the origin, with Gaussian noise along the view ray.
Eigen::Matrix2Xd box_l_shape(const Eigen::Vector2d& c, double yaw, double a, double b, int per_side, double sigma,
                             tinyline::common::SplitMixRandom& rng) {
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw)), v(-std::sin(yaw), std::cos(yaw));
  // The corner nearest the viewer and the two sides from it.
  Eigen::Vector2d best = Eigen::Vector2d::Zero(), su = Eigen::Vector2d::Zero(), sv = Eigen::Vector2d::Zero();
  double dmin = 1e9;
  for (const double i : {-1.0, 1.0})
    for (const double j : {-1.0, 1.0}) {
      const Eigen::Vector2d k = c + 0.5 * a * i * u + 0.5 * b * j * v;
      if (k.norm() < dmin) {
        dmin = k.norm();
        best = k;
        su = -i * u;
        sv = -j * v;
      }
    }
  Eigen::Matrix2Xd p(2, 2 * per_side);
  for (int k = 0; k < per_side; ++k) {
    const double t = (k + 0.5) / per_side;
    p.col(k) = best + t * a * su;
    p.col(per_side + k) = best + t * b * sv;
  }
  for (Eigen::Index k = 0; k < p.cols(); ++k) {
    const Eigen::Vector2d ray = p.col(k).normalized();
    p.col(k) += sigma * rng.normal() * ray;
  }
  return p;
}

double angle_diff_mod_half_pi(double a, double b) {
  const double d = std::remainder(a - b, kPi / 2);
  return std::abs(d);
}

}  // namespace

TEST(RectangleFit, TwoSidesOfABox) {
  tinyline::common::SplitMixRandom rng(3);
  const Eigen::Vector2d c(0.1, 0.8);
  const double yaw = 20.0 * kPi / 180.0;
  const auto p = box_l_shape(c, yaw, 0.4, 0.3, 60, 0.003, rng);
  hf::RectangleFitParams params;
  auto f = hf::fit_rectangle(p, params);
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_EQ(f.sides_visible, 2);
  EXPECT_LT(angle_diff_mod_half_pi(f.yaw_rad, yaw), 0.5 * kPi / 180.0);
  EXPECT_GE(f.points_used, 110);
  EXPECT_LT(f.rms_residual_m, 0.005);
  // Visible extents: the whole sides (0.4 and 0.3 m, in either order).
  const Eigen::Vector2d e = f.extent_m.cwiseAbs();
  EXPECT_NEAR(std::max(e.x(), e.y()), 0.4, 0.02);
  EXPECT_NEAR(std::min(e.x(), e.y()), 0.3, 0.02);
  ASSERT_TRUE(f.centre_m);
  EXPECT_LT((*f.centre_m - c).norm(), 0.02);
  // With the size known, the centre too.
  params.known_size_m = Eigen::Vector2d(0.3, 0.4);
  f = hf::fit_rectangle(p, params);
  ASSERT_TRUE(f.ok() && f.centre_m);
  EXPECT_LT((*f.centre_m - c).norm(), 0.01);
}

TEST(RectangleFit, OneSideWithKnownSizeAndViewpoints) {
  tinyline::common::SplitMixRandom rng(4);
  // The viewer at the origin looks straight at a box's 0.4 m face 0.6 m away.
  Eigen::Matrix2Xd p(2, 80);
  for (int k = 0; k < 80; ++k) p.col(k) = Eigen::Vector2d(-0.2 + 0.4 * (k + 0.5) / 80, 0.6 + 0.003 * rng.normal());
  std::vector<Eigen::Vector2d> origins{{0.0, 0.0}};
  std::vector<int> sensor(80, 0);
  hf::RectangleFitParams params;
  params.known_size_m = Eigen::Vector2d(0.4, 0.3);
  const auto f = hf::fit_rectangle(p, params, {origins, sensor});
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_EQ(f.sides_visible, 1);
  ASSERT_TRUE(f.centre_m);
  EXPECT_LT((*f.centre_m - Eigen::Vector2d(0.0, 0.75)).norm(), 0.01);
  // Without viewpoints the side of the box is unknown: no centre.
  EXPECT_FALSE(hf::fit_rectangle(p, params).centre_m);
}

TEST(RectangleFit, IgnoresThirtyPercentOutliers) {
  tinyline::common::SplitMixRandom rng(5);
  const Eigen::Vector2d c(-0.2, 0.9);
  const double yaw = -35.0 * kPi / 180.0;
  const auto box = box_l_shape(c, yaw, 0.5, 0.25, 70, 0.003, rng);
  Eigen::Matrix2Xd p(2, 200);
  p.leftCols(140) = box;
  for (int k = 140; k < 200; ++k) p.col(k) = Eigen::Vector2d(-1.0 + 2.0 * rng.uniform(), 0.2 + 1.5 * rng.uniform());
  hf::RectangleFitParams params;
  params.known_size_m = Eigen::Vector2d(0.5, 0.25);
  const auto f = hf::fit_rectangle(p, params);
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_EQ(f.sides_visible, 2);
  EXPECT_LT(angle_diff_mod_half_pi(f.yaw_rad, yaw), 1.0 * kPi / 180.0);
  ASSERT_TRUE(f.centre_m);
  EXPECT_LT((*f.centre_m - c).norm(), 0.015);
}

TEST(RectangleFit, DegenerateInputIsAnOutcome) {
  Eigen::Matrix2Xd few(2, 3);
  few << 0, 1, 2, 0, 0, 0;
  EXPECT_EQ(hf::fit_rectangle(few).detail, hf::FitStatus::kTooFewPoints);
  tinyline::common::SplitMixRandom rng(6);
  Eigen::Matrix2Xd scatter(2, 30);  // no 8 of them within 1.5 cm of a line
  for (int k = 0; k < 30; ++k) scatter.col(k) = Eigen::Vector2d(rng.uniform(), rng.uniform());
  const auto f = hf::fit_rectangle(scatter);
  EXPECT_EQ(f.detail, hf::FitStatus::kNoConsensus) << f.status.message;
  hf::RectangleFitParams bad;
  bad.inlier_threshold_m = 0.0;
  EXPECT_EQ(hf::fit_rectangle(scatter, bad).detail, hf::FitStatus::kInvalidParams);
}
