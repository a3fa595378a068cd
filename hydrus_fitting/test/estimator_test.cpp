// SPDX-License-Identifier: Apache-2.0
// The whole update (fuse the four sensors at their joint angles, filter the
// robot out, fit robustly) on exact planar geometry with Table 3.1 noise.
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "hydrus_fitting/estimator.hpp"
#include "planar_scene.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace ev = tinyline::hydrus_fitting::eval;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";
std::int64_t ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

struct Rig {
  hf::RobotModel model = hf::RobotModel::load(kConfig);
  hf::JointStateBuffer joints{model.joint_names()};
  std::vector<ev::SyntheticScan> scans;
  std::vector<hf::ScanView> views;

  Rig(const std::vector<double>& q, const ev::PlanarWorld& world, std::uint64_t seed = 1) {
    (void)joints.add(ns(1.0), model.joint_names(), q);
    tinyline::common::SplitMixRandom rng(seed);
    scans = ev::scan_all(model, q, world, {}, rng);
    for (const auto& s : scans) views.push_back({s.sensor, ns(1.0), s.angle_rad, s.range_m});
  }
};

}  // namespace

TEST(CircleEstimator, FourSensorsAroundACylinder) {
  // Joints at 60 degrees: an open hexagon arc whose centre is 0.433 m in
  // front of the links' middles; a 0.15 m cylinder there.
  const hf::Circle truth{{0.25, 0.433}, 0.15};
  const double t = 60.0 * kPi / 180.0;
  Rig s({t, t, t}, {{truth}, {}, true});
  hf::CircleEstimator est(s.model);
  const auto e = est.estimate(s.views, s.joints);
  ASSERT_TRUE(e.fit.ok()) << e.fit.status.message;
  EXPECT_EQ(e.scans_fused, 4);
  EXPECT_LT((e.fit.circle.centre_m - truth.centre_m).norm(), 0.004);
  EXPECT_NEAR(e.fit.circle.radius_m, truth.radius_m, 0.004);
  // Its covariance is honest: the errors are within a few of its SDs.
  EXPECT_LT(std::abs(e.fit.circle.radius_m - truth.radius_m), 5 * std::sqrt(e.fit.covariance(2, 2)));
}

TEST(CircleEstimator, SelfPointsAndClutterDoNotHoldTheFit) {
  // Closed square around a thin cylinder: every sensor also sees the links
  // across the square, and a wall segment adds clutter.
  const hf::Circle truth{{0.27, 0.24}, 0.06};
  ev::PlanarWorld world{{truth}, {{{-1.0, 1.2}, {1.5, 1.2}, 0.01}}, true};
  Rig s({kPi / 2, kPi / 2, kPi / 2}, world, 3);
  int robot_pixels = 0;
  for (const auto& sc : s.scans)
    for (const int k : sc.hit_kind) robot_pixels += (k == ev::kHitRobot);
  ASSERT_GT(robot_pixels, 200) << "the scene must show the robot to the sensors";
  hf::CircleEstimator est(s.model);
  const auto e = est.estimate(s.views, s.joints);
  ASSERT_TRUE(e.fit.ok()) << e.fit.status.message;
  EXPECT_GT(e.self_filtered, 150);
  EXPECT_LT((e.fit.circle.centre_m - truth.centre_m).norm(), 0.005);
  EXPECT_NEAR(e.fit.circle.radius_m, truth.radius_m, 0.005);
}

TEST(CircleEstimator, StaleAndUnknownScansAreReportedNotFused) {
  const hf::Circle truth{{0.25, 0.433}, 0.15};
  const double t = 60.0 * kPi / 180.0;
  Rig s({t, t, t}, {{truth}, {}, true});
  s.views[1].sensor = "laser7";
  s.views[2].stamp_ns = ns(0.5);  // half a second older than the others
  hf::CircleEstimator est(s.model);
  const auto e = est.estimate(s.views, s.joints);
  ASSERT_EQ(e.scans.size(), 4u);
  EXPECT_EQ(e.scans[1].status.code, tinyline::common::StatusCode::NotFound);
  EXPECT_THAT(e.scans[2].status.message, HasSubstr("older than the newest"));
  EXPECT_EQ(e.scans_fused, 2);
  EXPECT_TRUE(e.fit.ok()) << e.fit.status.message;  // two sensors still see enough
  // Nothing at all: an outcome with reasons.
  const auto none = est.estimate({}, s.joints);
  EXPECT_EQ(none.fit.detail, hf::FitStatus::kTooFewPoints);
  // Joint states far older than every scan: nothing fused, said so.
  hf::JointStateBuffer old(s.model.joint_names());
  (void)old.add(ns(0.0), s.model.joint_names(), std::vector<double>{t, t, t});
  Rig fresh({t, t, t}, {{truth}, {}, true});
  const auto stale = est.estimate(fresh.views, old);
  EXPECT_EQ(stale.scans_fused, 0);
  EXPECT_FALSE(stale.fit.ok());
  EXPECT_THAT(stale.fit.status.message, HasSubstr("no scan could be fused"));
  EXPECT_THAT(stale.fit.status.message, HasSubstr("older than the scan"));
}

namespace {

// The base flies along +y at 0.125 m/s turning at 0.2 rad/s; the cylinder
// stands still in the fixed frame. Each sensor's scan is taken 30 ms after
// the previous one (the thesis's sequence mode), exact ranges.
struct MovingBase {
  static constexpr double kSpeed = 0.125, kYawRate = 0.2;
  hf::RobotModel model = hf::RobotModel::load(kConfig);
  hf::JointStateBuffer joints{model.joint_names()};
  hf::BasePoseBuffer poses;
  std::vector<ev::SyntheticScan> scans;
  std::vector<hf::ScanView> views;
  Eigen::Vector2d centre_now = Eigen::Vector2d::Zero();  // the truth in the base frame at the newest scan

  static Eigen::Isometry2d base(double t) {
    return Eigen::Translation2d(0.0, kSpeed * t) * Eigen::Rotation2Dd(kYawRate * (t - 1.0));
  }

  explicit MovingBase(double radius = 0.15) {
    const double q = 60.0 * kPi / 180.0;
    const std::vector<double> qs{q, q, q};
    const Eigen::Vector2d fixed = base(1.09) * Eigen::Vector2d(0.25, 0.433);
    for (double t = 0.9; t < 1.2; t += 0.01) {
      (void)joints.add(ns(t), model.joint_names(), qs);
      const Eigen::Isometry2d b = base(t);
      (void)poses.add(ns(t), b.translation(), std::atan2(b.linear()(1, 0), b.linear()(0, 0)));
    }
    tinyline::common::SplitMixRandom rng(1);
    ev::SyntheticScanParams exact;
    exact.noise_scale = 0.0;
    for (std::size_t s = 0; s < model.sensors().size(); ++s) {
      const double t = 1.0 + 0.03 * static_cast<double>(s);
      const ev::PlanarWorld world{{hf::Circle{base(t).inverse() * fixed, radius}}, {}, false};
      scans.push_back(ev::scan_all(model, qs, world, exact, rng)[s]);
    }
    for (std::size_t s = 0; s < scans.size(); ++s)
      views.push_back({scans[s].sensor, ns(1.0 + 0.03 * static_cast<double>(s)), scans[s].angle_rad, scans[s].range_m});
    centre_now = base(1.09).inverse() * fixed;
  }
};

}  // namespace

TEST(CircleEstimator, TheBaseMotionBetweenScansIsCompensated) {
  MovingBase m;
  hf::CircleEstimator est(m.model);
  // Without the base's poses the four scans see the cylinder up to 11 mm
  // and 1 degree apart: the fit is smeared.
  const auto smeared = est.estimate(m.views, m.joints);
  ASSERT_TRUE(smeared.fit.ok()) << smeared.fit.status.message;
  EXPECT_FALSE(smeared.base_motion_compensated);
  const double before = (smeared.fit.circle.centre_m - m.centre_now).norm();
  EXPECT_GT(before, 0.003);
  // With them, every scan is moved to the newest one's base frame.
  const auto moved = est.estimate(m.views, m.joints, &m.poses);
  ASSERT_TRUE(moved.fit.ok()) << moved.fit.status.message;
  EXPECT_TRUE(moved.base_motion_compensated) << moved.base_motion_reason;
  EXPECT_EQ(moved.scans_fused, 4);
  const double after = (moved.fit.circle.centre_m - m.centre_now).norm();
  EXPECT_LT(after, 0.0005) << "before " << before;
  EXPECT_NEAR(moved.fit.circle.radius_m, 0.15, 0.0005);
  // The viewpoints moved with their points: the newest scan's sensor where the model puts it.
  const auto& cloud = est.cloud();
  ASSERT_EQ(cloud.views.size(), 4u);
  const double q = 60.0 * kPi / 180.0;
  const hf::Kinematics k = m.model.forward(std::vector<double>{q, q, q});
  EXPECT_LT((cloud.views[3] - k.T_base_sensor[3].translation()).norm(), 1e-9);
  EXPECT_GT((cloud.views[0] - k.T_base_sensor[0].translation()).norm(), 0.005);
}

TEST(CircleEstimator, MissingBasePosesMoveNoScanAndSayWhy) {
  MovingBase m;
  hf::CircleEstimator est(m.model);
  const auto plain = est.estimate(m.views, m.joints);
  // No pose at all.
  const hf::BasePoseBuffer empty;
  const auto none = est.estimate(m.views, m.joints, &empty);
  EXPECT_FALSE(none.base_motion_compensated);
  EXPECT_THAT(none.base_motion_reason, HasSubstr("no base pose received yet"));
  ASSERT_TRUE(none.fit.ok());
  EXPECT_EQ(none.fit.circle.centre_m, plain.fit.circle.centre_m);  // exactly the uncompensated fit
  // Poses that stop before the newest scans: all or none, never a mix.
  hf::BasePoseBuffer early;
  for (double t = 0.9; t < 1.03; t += 0.01) {
    const Eigen::Isometry2d b = MovingBase::base(t);
    (void)early.add(ns(t), b.translation(), std::atan2(b.linear()(1, 0), b.linear()(0, 0)));
  }
  const auto partial = est.estimate(m.views, m.joints, &early);
  EXPECT_FALSE(partial.base_motion_compensated);
  EXPECT_THAT(partial.base_motion_reason, HasSubstr("newest base pose is"));
  EXPECT_THAT(partial.base_motion_reason, HasSubstr("no scan moved"));
  EXPECT_EQ(partial.fit.circle.centre_m, plain.fit.circle.centre_m);
}
