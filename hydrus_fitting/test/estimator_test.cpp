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
    hf::detail::SplitMix64 rng(seed);
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
  ASSERT_TRUE(e.fit.ok()) << e.fit.reason;
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
  ASSERT_TRUE(e.fit.ok()) << e.fit.reason;
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
  EXPECT_EQ(e.scans[1].status, hf::ScanStatus::kUnknownSensor);
  EXPECT_THAT(e.scans[2].reason, HasSubstr("older than the newest"));
  EXPECT_EQ(e.scans_fused, 2);
  EXPECT_TRUE(e.fit.ok()) << e.fit.reason;  // two sensors still see enough
  // Nothing at all: an outcome with reasons.
  const auto none = est.estimate({}, s.joints);
  EXPECT_EQ(none.fit.status, hf::FitStatus::kTooFewPoints);
  // Joint states far older than every scan: nothing fused, said so.
  hf::JointStateBuffer old(s.model.joint_names());
  (void)old.add(ns(0.0), s.model.joint_names(), std::vector<double>{t, t, t});
  Rig fresh({t, t, t}, {{truth}, {}, true});
  const auto stale = est.estimate(fresh.views, old);
  EXPECT_EQ(stale.scans_fused, 0);
  EXPECT_FALSE(stale.fit.ok());
  EXPECT_THAT(stale.fit.reason, HasSubstr("no scan could be fused"));
  EXPECT_THAT(stale.fit.reason, HasSubstr("older than the scan"));
}
