// SPDX-License-Identifier: Apache-2.0
// Tomato registration on hand-made scans through a truss's tomatoes: the
// vision's common offset recovered, a repeating truss reported ambiguous
// rather than guessed, and bad input answered with a reason.
#include <cmath>
#include <limits>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/tomato_registration.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
using lc::test::Disc;
using lc::test::synth_scan;
using lc::test::SynthParams;
using ::testing::HasSubstr;

namespace {

SynthParams wall(unsigned seed) {
  SynthParams sp;
  sp.wall_z_m = 0.45;
  sp.noise_sd_m = 0.003;
  sp.seed = seed;
  return sp;
}

// The vision's tomatoes: the true ones moved back by `offset` (what the
// registration must find), each off by its own few millimetres, their
// centres `height` off the plane.
std::vector<lc::ExpectedTomato> vision(const std::vector<Disc>& truth, const Eigen::Vector2d& offset,
                                       double height = 0.0) {
  std::vector<lc::ExpectedTomato> out;
  const double jitter[][2] = {{0.002, -0.003}, {-0.003, 0.001}, {0.001, 0.003}, {-0.002, -0.002}};
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const double r = std::sqrt(truth[i].radius_m * truth[i].radius_m + height * height);  // its cut is truth's disc
    out.push_back({Eigen::Vector3d(truth[i].x_m - offset.x() + jitter[i % 4][0], height,
                                   truth[i].z_m - offset.y() + jitter[i % 4][1]),
                   r});
  }
  return out;
}

}  // namespace

TEST(TomatoRegistration, RecoversTheVisionsCommonOffset) {
  // Four tomatoes, each its own size and depth, cut 1 cm below their centres.
  const std::vector<Disc> truth{{-0.11, 0.23, 0.028, 6.0, 1},
                                {-0.04, 0.21, 0.033, 6.0, 2},
                                {0.035, 0.24, 0.026, 6.0, 3},
                                {0.10, 0.22, 0.031, 6.0, 4}};
  for (const Eigen::Vector2d& offset :
       {Eigen::Vector2d(0.03, -0.015), Eigen::Vector2d(-0.045, 0.01), Eigen::Vector2d(0.0, 0.0)}) {
    const auto s = synth_scan(truth, wall(11));
    const auto r = lc::register_tomatoes(s.scan, vision(truth, offset, 0.01));
    ASSERT_TRUE(r.status.ok()) << r.status.message;
    EXPECT_NEAR(r.shift_xz_m.x(), offset.x(), 0.004);
    EXPECT_NEAR(r.shift_xz_m.y(), offset.y(), 0.004);
    EXPECT_EQ(r.tomatoes_in_plane, 4);
    EXPECT_GE(r.tomatoes_matched, 3);
    EXPECT_LT(r.rms_m, 0.005);
    EXPECT_LT(r.runner_up_support, 0.8 * r.support);
  }
}

TEST(TomatoRegistration, ARepeatingTrussIsAmbiguousNotGuessed) {
  // Five equal tomatoes 7 cm apart in a row; the vision saw three of them:
  // a shift by one spacing fits as well as the true one.
  std::vector<Disc> truth;
  for (int k = -2; k <= 2; ++k) truth.push_back({0.07 * k, 0.22, 0.03, 6.0, k + 3});
  const std::vector<Disc> seen(truth.begin() + 1, truth.begin() + 4);
  const auto s = synth_scan(truth, wall(12));
  const auto r = lc::register_tomatoes(s.scan, vision(seen, {0.0, 0.0}));
  EXPECT_EQ(r.status.code, tinyline::StatusCode::NotFound);
  EXPECT_THAT(r.status.message, HasSubstr("ambiguous"));
  EXPECT_GT(r.runner_up_support, 0.8 * r.support);
}

TEST(TomatoRegistration, FreeSpaceRulesOutAShiftThatPutsATomatoWhereTheLaserSeesThrough) {
  // Three tomatoes in a row, the right one hidden behind a leaf nearer the
  // laser. Shifted left by one spacing, the vision's layout puts its middle
  // and right tomatoes on the two seen arcs as well as the true shift does;
  // but its left tomato then lies where the laser sees the wall behind.
  const Disc left{-0.035, 0.22, 0.03, 6.0, 1}, middle{0.035, 0.22, 0.03, 6.0, 2}, right{0.105, 0.22, 0.03, 6.0, 3};
  const Disc leaf{0.105 * 0.12 / 0.22, 0.12, 0.02, 4.0, 4};  // on the right tomato's bearing
  const auto s = synth_scan({left, middle, right, leaf}, wall(13));
  const auto expected = vision({left, middle, right}, {0.0, 0.0});
  const auto r = lc::register_tomatoes(s.scan, expected);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_NEAR(r.shift_xz_m.x(), 0.0, 0.004);
  EXPECT_NEAR(r.shift_xz_m.y(), 0.0, 0.004);
  EXPECT_LE(r.violations, 2);
  lc::TomatoRegistrationParams arcs_only;
  arcs_only.violation_cost = arcs_only.no_return_cost = 0.0;
  const auto a = lc::register_tomatoes(s.scan, expected, arcs_only);
  EXPECT_FALSE(a.status.ok()) << "arcs alone cannot tell the two shifts apart: " << a.status.message;
  EXPECT_GT(a.runner_up_support, 0.8 * a.support);
}

TEST(TomatoRegistration, TooFewTomatoesInThePlaneOrInTheScanIsNoRegistration) {
  const std::vector<Disc> truth{{0.0, 0.22, 0.03, 6.0, 1}};
  const auto s = synth_scan(truth, wall(14));
  const auto one = lc::register_tomatoes(s.scan, vision(truth, {0.01, 0.0}));
  EXPECT_FALSE(one.status.ok());
  EXPECT_THAT(one.status.message, HasSubstr("need 2"));
  // Centres 4 cm off the plane: no tomato is cut by it.
  const auto above = lc::register_tomatoes(
      s.scan, {{{Eigen::Vector3d(0.0, 0.04, 0.22), 0.03}, {Eigen::Vector3d(0.07, 0.04, 0.22), 0.03}}});
  EXPECT_FALSE(above.status.ok());
  EXPECT_THAT(above.status.message, HasSubstr("cut by the laser plane"));
  EXPECT_EQ(above.tomatoes_in_plane, 0);
}

TEST(TomatoRegistration, BadInputIsAnErrorWithAReasonNeverACrash) {
  const std::vector<Disc> truth{{-0.035, 0.22, 0.03, 6.0, 1}, {0.035, 0.22, 0.03, 6.0, 2}};
  const auto s = synth_scan(truth, wall(15));
  const auto tomatoes = vision(truth, {0.0, 0.0});
  const double nan = std::numeric_limits<double>::quiet_NaN();

  EXPECT_THAT(lc::register_tomatoes(s.scan, {}).status.message, HasSubstr("cut by the laser plane"));
  auto bad = tomatoes;
  bad[1].centre_m.x() = nan;
  EXPECT_THAT(lc::register_tomatoes(s.scan, bad).status.message, HasSubstr("tomato 1"));
  bad = tomatoes;
  bad[0].radius_m = -0.01;
  EXPECT_THAT(lc::register_tomatoes(s.scan, bad).status.message, HasSubstr("tomato 0"));

  lc::TomatoRegistrationParams p;
  p.grid_step_m = 0.0;
  EXPECT_THAT(lc::register_tomatoes(s.scan, tomatoes, p).status.message, HasSubstr("grid_step_m"));
  p = {};
  p.inlier_m = nan;
  EXPECT_THAT(lc::register_tomatoes(s.scan, tomatoes, p).status.message, HasSubstr("inlier_m"));
  p = {};
  p.core_fraction = 1.5;
  EXPECT_THAT(lc::register_tomatoes(s.scan, tomatoes, p).status.message, HasSubstr("core_fraction"));
  p = {};
  p.violation_cost = -1.0;
  EXPECT_THAT(lc::register_tomatoes(s.scan, tomatoes, p).status.message, HasSubstr("violation_cost"));
  p = {};
  p.ambiguity_ratio = 1.5;
  EXPECT_THAT(lc::register_tomatoes(s.scan, tomatoes, p).status.message, HasSubstr("ambiguity_ratio"));

  lc::LineScan empty;
  EXPECT_THAT(lc::register_tomatoes(empty, tomatoes).status.message, HasSubstr("no return"));
  lc::LineScan all_invalid = s.scan;
  for (auto& r : all_invalid.range_m) r = nan;
  EXPECT_THAT(lc::register_tomatoes(all_invalid, tomatoes).status.message, HasSubstr("no return"));
  lc::LineScan short_angles = s.scan;
  short_angles.angle_rad.pop_back();
  EXPECT_THAT(lc::register_tomatoes(short_angles, tomatoes).status.message, HasSubstr("angles"));
}
