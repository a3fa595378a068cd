// SPDX-License-Identifier: Apache-2.0
// Fusion: scans placed in the robot frame with the joint angles at their own
// timestamps, the self-filter of 6.2.3, and every bad input as an outcome.
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "hydrus_fitting/base_motion.hpp"
#include "hydrus_fitting/fusion.hpp"

namespace hf = tinyline::hydrus_fitting;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";

std::int64_t ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

/// A 256-pixel scan of the 3.6 mm lens (angles atan(u / f)), all at one range.
struct Scan {
  std::vector<double> angle, range;
  explicit Scan(double r, int n = 256) {
    for (int i = 0; i < n; ++i) {
      const double u_mm = (i + 0.5 - 0.5 * n) * 5.12 / 256.0;
      angle.push_back(std::atan(u_mm / 3.6));
      range.push_back(r);
    }
  }
  hf::ScanView view(const char* sensor, double t_s) const { return {sensor, ns(t_s), angle, range}; }
};

hf::JointStateBuffer joints_at(const hf::RobotModel& m, double t_s, std::vector<double> q) {
  hf::JointStateBuffer b(m.joint_names());
  (void)b.add(ns(t_s), m.joint_names(), q);
  return b;
}

}  // namespace

TEST(Fusion, PlacesPixelsInTheRobotFrame) {
  const auto m = hf::RobotModel::load(kConfig);
  const auto joints = joints_at(m, 1.0, {0, 0, 0});
  hf::ScanFuser fuser(m);
  const Scan scan(0.4);
  const auto out = fuser.add(scan.view("laser2", 1.0), joints);
  ASSERT_TRUE(out.ok()) << out.status.message;
  EXPECT_EQ(out.sensor, 1);
  EXPECT_EQ(out.added, 256);
  const auto& c = fuser.cloud();
  ASSERT_EQ(c.size(), 256);
  // laser2 at (0.75, 0.05) looking +y; line axis left: positive angles go to -x.
  const auto p = c.points_m();
  for (int i = 0; i < 256; ++i) {
    const double a = scan.angle[static_cast<std::size_t>(i)];
    const Eigen::Vector2d expect(0.75 - 0.4 * std::sin(a), 0.05 + 0.4 * std::cos(a));
    EXPECT_NEAR((p.col(i) - expect).norm(), 0.0, 1e-12) << i;
  }
  EXPECT_NEAR(c.sigma_m[0], hf::RangeNoiseModel{}.sd_at(0.4), 1e-15);
  EXPECT_EQ(c.views.size(), 1u);
  EXPECT_NEAR((c.views[0] - Eigen::Vector2d(0.75, 0.05)).norm(), 0.0, 1e-12);
}

TEST(Fusion, EachScanUsesTheJointsAtItsOwnTimestamp) {
  const auto m = hf::RobotModel::load(kConfig);
  hf::JointStateBuffer joints(m.joint_names());
  (void)joints.add(ns(1.0), m.joint_names(), std::vector<double>{0.0, 0.0, 0.0});
  (void)joints.add(ns(1.1), m.joint_names(), std::vector<double>{0.4, 0.0, 0.0});
  hf::ScanFuser fuser(m);
  const Scan scan(0.5, 1);  // one pixel on the optical axis... nearly (angle of pixel 0 of 1)
  for (const double t : {1.0, 1.05, 1.1}) {
    fuser.clear();
    ASSERT_TRUE(fuser.add(scan.view("laser2", t), joints).ok());
    const double q = 0.4 * (t - 1.0) / 0.1;
    const auto k = m.forward(std::vector<double>{q, 0.0, 0.0});
    const Eigen::Vector2d expect = k.T_base_sensor[1] * (0.5 * m.sensors()[1].ray(scan.angle[0]));
    EXPECT_NEAR((fuser.cloud().points_m().col(0) - expect).norm(), 0.0, 1e-12) << t;
  }
}

TEST(Fusion, BadInputIsAnOutcomeNeverACrash) {
  const auto m = hf::RobotModel::load(kConfig);
  hf::ScanFuser fuser(m);
  const Scan scan(0.4);
  // Unknown sensor: names the sensor and the ones the description has.
  const auto joints = joints_at(m, 1.0, {0, 0, 0});
  auto out = fuser.add(scan.view("laser9", 1.0), joints);
  EXPECT_EQ(out.status.code, tinyline::common::StatusCode::NotFound);
  EXPECT_THAT(out.status.message,
              HasSubstr("'laser9' is not in the robot description 'hydrus4' (it has: laser1, laser2"));
  // Stale joints.
  out = fuser.add(scan.view("laser1", 1.5), joints);
  EXPECT_EQ(out.status.code, tinyline::common::StatusCode::OutOfRange);
  EXPECT_EQ(out.joints, hf::JointLookupStatus::kStale);
  EXPECT_THAT(out.status.message, HasSubstr("older than the scan"));
  // No joint state at all.
  hf::JointStateBuffer empty(m.joint_names());
  EXPECT_EQ(fuser.add(scan.view("laser1", 1.0), empty).joints, hf::JointLookupStatus::kNoData);
  // Mismatched arrays.
  std::vector<double> short_range(10, 0.4);
  out = fuser.add({"laser1", ns(1.0), scan.angle, short_range}, joints);
  EXPECT_EQ(out.status.code, tinyline::common::StatusCode::InvalidArgument);
  EXPECT_THAT(out.status.message, HasSubstr("256 angles but 10 ranges"));
  // Wrong number of joint angles.
  EXPECT_EQ(fuser.add(scan.view("laser1", 1.0), std::vector<double>{0.0}).status.code,
            tinyline::common::StatusCode::InvalidArgument);
  EXPECT_EQ(fuser.cloud().size(), 0);  // nothing was added by any of these
  // NaN, zero, negative and out-of-range pixels are counted, not fused.
  Scan odd(0.4);
  odd.range[0] = std::numeric_limits<double>::quiet_NaN();
  odd.range[1] = 0.0;
  odd.range[2] = -1.0;
  odd.range[3] = 0.01;  // below the 5 cm minimum
  odd.range[4] = 2.5;   // beyond 2 m
  odd.angle[5] = std::numeric_limits<double>::infinity();
  out = fuser.add(odd.view("laser1", 1.0), joints);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out.invalid, 4);
  EXPECT_EQ(out.out_of_range, 2);
  EXPECT_EQ(out.added, 250);
}

TEST(Fusion, SelfFilterRemovesPointsOnTheRobotsOwnLinks) {
  // Square chain: laser1 looks across the square at link 3 (0.5 m away, along
  // y = 0.5). A scan that reaches exactly to link 3's near face hits the robot.
  const auto m = hf::RobotModel::load(kConfig);
  const auto joints = joints_at(m, 1.0, {kPi / 2, kPi / 2, kPi / 2});
  const Scan scan(1.0);
  std::vector<double> range(scan.angle.size());
  for (std::size_t i = 0; i < range.size(); ++i) {
    // Sensor at (0.25, 0.05) looking +y; link 3's inner face is at y = 0.5 - 0.04.
    range[i] = (0.46 - 0.05) / std::cos(scan.angle[i]);
  }
  hf::ScanFuser fuser(m);
  auto out = fuser.add({"laser1", ns(1.0), scan.angle, range}, joints);
  ASSERT_TRUE(out.ok());
  // Pixels whose point lands on link 3 (x in [0, 0.5]) or on links 2/4 are removed.
  EXPECT_GT(out.self_filtered, 200);
  for (int i = 0; i < fuser.cloud().size(); ++i) {
    const auto k = m.forward(std::vector<double>{kPi / 2, kPi / 2, kPi / 2});
    EXPECT_FALSE(hf::on_robot(m, k, fuser.cloud().points_m().col(i), 0.03));
  }
  // With the filter off, everything stays.
  hf::FusionParams off;
  off.self_filter = false;
  hf::ScanFuser raw(m, off);
  out = raw.add({"laser1", ns(1.0), scan.angle, range}, joints);
  EXPECT_EQ(out.self_filtered, 0);
  EXPECT_EQ(out.added, 256 - out.out_of_range);
}

TEST(Fusion, RangeNoiseModelInterpolatesTable31) {
  const hf::RangeNoiseModel n;
  EXPECT_DOUBLE_EQ(n.sd_at(0.1), 0.003625);  // held below 20.5 cm
  EXPECT_DOUBLE_EQ(n.sd_at(0.5), 0.006164);
  EXPECT_NEAR(n.sd_at(0.875), 0.5 * (0.006385 + 0.010480), 1e-12);
  EXPECT_DOUBLE_EQ(n.sd_at(3.0), 0.019593);  // held beyond 125 cm
}

TEST(BasePoseBuffer, InterpolatesPoseAndYawTheShortWayRound) {
  hf::BasePoseBuffer b;
  EXPECT_TRUE(b.add(ns(1.1), {1.0, 2.0}, -3.1));  // out of order: placed by time
  EXPECT_TRUE(b.add(ns(1.0), {0.0, 0.0}, 3.1));
  const auto mid = b.at(ns(1.05));
  ASSERT_TRUE(mid.status.ok()) << mid.status.message;
  EXPECT_NEAR(mid.T_fixed_base.translation().x(), 0.5, 1e-12);
  EXPECT_NEAR(mid.T_fixed_base.translation().y(), 1.0, 1e-12);
  // 3.1 to -3.1 rad is 0.083 rad through pi, not 6.2 rad the other way.
  const double yaw = std::atan2(mid.T_fixed_base.linear()(1, 0), mid.T_fixed_base.linear()(0, 0));
  EXPECT_NEAR(std::abs(yaw), kPi, 1e-9);
  // A pose replaced at the same stamp.
  EXPECT_TRUE(b.add(ns(1.1), {2.0, 2.0}, -3.1));
  EXPECT_NEAR(b.at(ns(1.1)).T_fixed_base.translation().x(), 2.0, 1e-12);
}

TEST(BasePoseBuffer, MotionMapsAPointSeenEarlierIntoTheLaterBaseFrame) {
  hf::BasePoseBuffer b;
  ASSERT_TRUE(b.add(ns(0.0), {0.0, 0.0}, 0.0));
  ASSERT_TRUE(b.add(ns(1.0), {0.0, 1.0}, kPi / 2));
  // A point 1 m to the left (+y) of the base at t = 0: the base at t = 1
  // stands on it, turned a quarter to the left, so the base's origin at
  // t = 0 is 1 m straight behind it, (-1, 0).
  const auto m = b.motion(ns(0.0), ns(1.0));
  ASSERT_TRUE(m.status.ok()) << m.status.message;
  EXPECT_LT((m.T_fixed_base * Eigen::Vector2d(0.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((m.T_fixed_base * Eigen::Vector2d(0.0, 0.0) - Eigen::Vector2d(-1.0, 0.0)).norm(), 1e-12);
}

TEST(BasePoseBuffer, BadInputIsAnOutcomeWithAReason) {
  hf::BasePoseBuffer b(hf::BasePoseBufferParams{0.02, 2.0});
  EXPECT_THAT(b.at(ns(1.0)).status.message, HasSubstr("no base pose received yet"));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(b.add(ns(1.0), {nan, 0.0}, 0.0));
  EXPECT_FALSE(b.add(ns(1.0), {0.0, 0.0}, std::numeric_limits<double>::infinity()));
  EXPECT_TRUE(b.empty());
  ASSERT_TRUE(b.add(ns(1.0), {0.0, 0.0}, 0.0));
  EXPECT_TRUE(b.at(ns(1.015)).status.ok());  // within the tolerance: held
  const auto stale = b.at(ns(1.1));
  EXPECT_FALSE(stale.status.ok());
  EXPECT_EQ(stale.status.code, tinyline::common::StatusCode::OutOfRange);
  EXPECT_THAT(stale.status.message, HasSubstr("newest base pose is 0.100 s older than the scan"));
  EXPECT_THAT(b.at(ns(0.5)).status.message, HasSubstr("oldest kept base pose is 0.500 s newer"));
  EXPECT_THROW(hf::BasePoseBuffer(hf::BasePoseBufferParams{-1.0, 2.0}), std::invalid_argument);
}
