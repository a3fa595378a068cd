// SPDX-License-Identifier: Apache-2.0
// The grasp manoeuvre: fly in open, close, hold; clamped and validated.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "hydrus_fitting/trajectory.hpp"

using namespace tinyline::hydrus_fitting;

TEST(ApproachTrajectory, FliesInThenClosesThenHolds) {
  ApproachParams p;
  const RobotPose2D start = approach_pose(p, 0.0);
  EXPECT_NEAR(start.base_xy_m.x(), -0.25, 1e-12);
  EXPECT_NEAR(start.base_xy_m.y(), -0.4330127018922193 - 0.75, 1e-12);
  ASSERT_EQ(start.joints_rad.size(), 3u);
  EXPECT_NEAR(start.joints_rad[0], p.open_joint_rad, 1e-12);

  const RobotPose2D mid = approach_pose(p, 0.5 * p.approach_s);
  EXPECT_NEAR(mid.base_xy_m.y(), -0.4330127018922193 - 0.375, 1e-12);
  EXPECT_NEAR(mid.joints_rad[1], p.open_joint_rad, 1e-12);

  const RobotPose2D closing = approach_pose(p, p.approach_s + 0.5 * p.close_s);
  EXPECT_NEAR(closing.base_xy_m.y(), -0.4330127018922193, 1e-12);
  EXPECT_NEAR(closing.joints_rad[2], 0.5 * (p.open_joint_rad + p.closed_joint_rad), 1e-12);

  const RobotPose2D held = approach_pose(p, p.duration_s() + 5.0);  // clamped
  EXPECT_NEAR(held.joints_rad[0], p.closed_joint_rad, 1e-12);
  const RobotPose2D before = approach_pose(p, -3.0);
  EXPECT_NEAR(before.base_xy_m.y(), -0.4330127018922193 - 0.75, 1e-12);
  const RobotPose2D nan = approach_pose(p, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(nan.base_xy_m.allFinite());
}

TEST(ApproachTrajectory, ZeroLengthPhasesJump) {
  ApproachParams p;
  p.approach_s = 0.0;
  p.close_s = 0.0;
  EXPECT_NEAR(approach_pose(p, 0.0).joints_rad[0], p.closed_joint_rad, 1e-12);
  EXPECT_NEAR(approach_pose(p, 0.0).base_xy_m.y(), -0.4330127018922193, 1e-12);
}

TEST(ApproachTrajectory, BadParametersAreNamed) {
  ApproachParams p;
  EXPECT_TRUE(p.validate().ok());
  p.close_s = -1.0;
  EXPECT_NE(p.validate().message.find("durations"), std::string::npos);
  p = {};
  p.approach_direction.setZero();
  EXPECT_NE(p.validate().message.find("approach_direction"), std::string::npos);
  p = {};
  p.start_distance_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(p.validate().message.find("start_distance_m"), std::string::npos);
}
