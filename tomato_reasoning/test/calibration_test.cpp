// SPDX-License-Identifier: Apache-2.0
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tomato_reasoning/calibration.hpp"
#include "tomato_reasoning/eval/scenario.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {
// A camera whose depth is off by a smooth image-dependent bias plus a
// quadratic in depth, measuring flat targets at known depths.
double bias(int u, int v, double z) {
  return 0.004 * std::sin(u / 200.0) - 0.003 * (v / 480.0) + 0.006 * z + 0.01 * z * z;
}
std::vector<DepthSample> frames(std::vector<double> depths, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.001);
  std::vector<DepthSample> out;
  for (double z : depths)
    for (int v = 0; v < 480; v += 8)
      for (int u = 0; u < 640; u += 8) out.push_back({u, v, z - bias(u, v, z) + noise(rng), z});
  return out;
}
}  // namespace

TEST(DepthCorrection, FitsZuvAndThetaAndCorrectsHeldOutDepths) {
  const DepthCorrection d = fit_depth_correction(frames({0.4, 0.6, 0.8, 1.0, 1.2, 1.4}, 1), 640, 480);
  ASSERT_TRUE(d.status.ok()) << d.status.message;
  EXPECT_EQ(d.empty_cells, 0);
  EXPECT_LT(d.rms_after_m, d.rms_before_m / 5);
  // Held out: depths between the fitted ones, other noise.
  double before = 0, after = 0;
  const auto test = frames({0.5, 0.9, 1.3}, 2);
  for (const auto& s : test) {
    before += std::pow(s.true_m - s.measured_m, 2);
    after += std::pow(s.true_m - d.correct(s.u, s.v, s.measured_m), 2);
  }
  before = std::sqrt(before / double(test.size()));
  after = std::sqrt(after / double(test.size()));
  EXPECT_GT(before, 0.01);
  EXPECT_LT(after, 0.0015);  // noise 1 mm + the piecewise-constant Z's residual
}

TEST(DepthCorrection, BadInputGivesNoModelAndTheReason) {
  EXPECT_FALSE(fit_depth_correction({}, 640, 480).status.ok());
  EXPECT_NE(fit_depth_correction({}, 640, 480).status.message.find("usable samples"), std::string::npos);
  std::vector<DepthSample> nan(500, DepthSample{1, 1, std::nan(""), 0.5});
  EXPECT_FALSE(fit_depth_correction(nan, 640, 480).status.ok());
  DepthCorrectionParams bad;
  bad.cells_u = 0;
  EXPECT_NE(fit_depth_correction(frames({0.5}, 1), 640, 480, bad).status.message.find("cells"), std::string::npos);
  EXPECT_FALSE(fit_depth_correction(frames({0.5}, 1), 0, 480).status.ok());
  // A model that is not ok leaves depths alone.
  EXPECT_EQ(DepthCorrection{}.correct(3, 4, 0.7), 0.7);
}

TEST(HandToHead, IcpRecoversTheHandCameraPoseFromAnOffGuess) {
  eval::ScenarioOptions o;
  o.views = 2;
  o.pose_noise_m = 0;  // T_ref_camera[1] is then the true pose of the second camera in the first's frame
  o.pose_noise_deg = 0;
  const eval::Scenario s = eval::make_scenario(sim::TrussClass::kB, 5, o);
  const Eigen::Isometry3d truth = s.T_ref_camera[1];
  Eigen::Isometry3d guess = truth;
  guess.translation() += Eigen::Vector3d(0.008, -0.006, 0.005);
  guess.linear() =
      guess.linear() * Eigen::AngleAxisd(1.5 * M_PI / 180, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  const HandToHeadResult r = calibrate_hand_to_head(s.clouds[0], s.clouds[1], guess);
  ASSERT_TRUE(r.ok()) << r.status.message;
  EXPECT_LT((r.T_head_hand.translation() - truth.translation()).norm(), 0.003);
  EXPECT_LT(Eigen::AngleAxisd(r.T_head_hand.linear().transpose() * truth.linear()).angle(), 0.4 * M_PI / 180);
  EXPECT_GT(r.overlap, 0.5);
}

TEST(HandToHead, BadInputGivesNoPoseAndTheReason) {
  ColorCloud empty;
  EXPECT_FALSE(calibrate_hand_to_head(empty, empty, Eigen::Isometry3d::Identity()).ok());
  ColorCloud broken;
  broken.xyz.resize(3);
  EXPECT_NE(calibrate_hand_to_head(broken, empty, Eigen::Isometry3d::Identity()).status.message.find("head cloud"),
            std::string::npos);
  ColorCloud few;
  few.push_back({0, 0, 1}, {1, 1, 1});
  EXPECT_NE(calibrate_hand_to_head(few, few, Eigen::Isometry3d::Identity()).status.message.find("too few"),
            std::string::npos);
}
