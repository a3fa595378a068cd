// SPDX-License-Identifier: Apache-2.0
// Robot description loading (errors with file, line, field), planar forward
// kinematics, and the joint-state buffer (interpolation, stale states).
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "hydrus_fitting/robot_model.hpp"

namespace hf = tinyline::hydrus_fitting;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";

const char* kTwoLinks = R"(name: two
links:
  - {name: a, length_m: 0.5, width_m: 0.1}
  - {name: b, length_m: 0.4, joint: {name: j1, limits_deg: [-90, 90]}}
sensors:
  - {name: s1, link: a, position_m: [0.2, 0.05], yaw_deg: 90}
  - {name: s2, link: b, position_m: [0.1, -0.05], yaw_deg: -90, line_axis: right}
)";

/// The error message of parsing `text`, or "" if it parses.
std::string parse_error(const std::string& text) {
  try {
    (void)hf::RobotModel::parse(text, "robot.yaml");
  } catch (const hf::RobotModelError& e) {
    return e.what();
  }
  return "";
}

std::int64_t ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

}  // namespace

TEST(RobotModel, LoadsTheShippedHydrus) {
  const auto m = hf::RobotModel::load(kConfig);
  EXPECT_EQ(m.name(), "hydrus4");
  ASSERT_EQ(m.links().size(), 4u);
  ASSERT_EQ(m.sensors().size(), 4u);
  EXPECT_EQ(m.joint_names(), (std::vector<std::string>{"joint1", "joint2", "joint3"}));
  EXPECT_EQ(m.sensor_index("laser3"), 2);
  EXPECT_FALSE(m.sensor_index("laser9"));
  // 3.6 mm over 5.12 mm: a 71 deg field of view.
  EXPECT_NEAR(2 * m.sensors()[0].fov_half_angle_rad() * 180 / kPi, 70.8, 0.1);
}

TEST(RobotModel, ForwardKinematicsOfAStraightAndASquareChain) {
  const auto m = hf::RobotModel::load(kConfig);
  const std::vector<double> straight{0, 0, 0};
  const auto k0 = m.forward(straight);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR((k0.T_base_link[static_cast<std::size_t>(i)].translation() - Eigen::Vector2d(0.5 * i, 0)).norm(), 0,
                1e-12);
  }
  // Sensor 1 at the middle of link 1, 5 cm to the left, looking left (+y).
  EXPECT_NEAR((k0.T_base_sensor[0].translation() - Eigen::Vector2d(0.25, 0.05)).norm(), 0, 1e-12);
  EXPECT_NEAR((k0.T_base_sensor[0].linear() * Eigen::Vector2d::UnitX() - Eigen::Vector2d::UnitY()).norm(), 0, 1e-12);

  // 90 degrees at every joint: a closed square of side 0.5 m, sensors looking at its centre.
  const std::vector<double> square{kPi / 2, kPi / 2, kPi / 2};
  const auto k = m.forward(square);
  EXPECT_NEAR((k.T_base_link[1].translation() - Eigen::Vector2d(0.5, 0.0)).norm(), 0, 1e-12);
  EXPECT_NEAR((k.T_base_link[2].translation() - Eigen::Vector2d(0.5, 0.5)).norm(), 0, 1e-12);
  EXPECT_NEAR((k.T_base_link[3].translation() - Eigen::Vector2d(0.0, 0.5)).norm(), 0, 1e-12);
  const Eigen::Vector2d centre(0.25, 0.25);
  for (std::size_t s = 0; s < 4; ++s) {
    const auto& T = k.T_base_sensor[s];
    const Eigen::Vector2d axis = T.linear() * Eigen::Vector2d::UnitX();
    const Eigen::Vector2d to_centre = (centre - T.translation()).normalized();
    EXPECT_NEAR(axis.dot(to_centre), 1.0, 1e-12) << "sensor " << s;
  }
  EXPECT_THROW((void)m.forward(std::vector<double>{0.0}), std::invalid_argument);
}

TEST(RobotModel, PixelRaysFollowTheLineAxis) {
  const auto m = hf::RobotModel::parse(kTwoLinks);
  const double a = 0.3;
  EXPECT_NEAR((m.sensors()[0].ray(a) - Eigen::Vector2d(std::cos(a), std::sin(a))).norm(), 0, 1e-15);
  EXPECT_NEAR((m.sensors()[1].ray(a) - Eigen::Vector2d(std::cos(a), -std::sin(a))).norm(), 0, 1e-15);
}

TEST(RobotModel, ErrorsNameFileLineAndField) {
  EXPECT_THAT(parse_error("name: x\nlinks:\n  - {name: a, length_m: 0.5, colour: red}\nsensors: []\n"),
              HasSubstr("robot.yaml:3: links[0].colour: unknown key"));
  EXPECT_THAT(
      parse_error(
          "links:\n  - {name: a, length_m: -1}\nsensors:\n  - {name: s, link: a, position_m: [0, 0], yaw_deg: 0}\n"),
      HasSubstr("robot.yaml:2: links[0].length_m: must be > 0"));
  EXPECT_THAT(parse_error("links:\n  - {name: a, length_m: 1}\n  - {name: b, length_m: 1}\nsensors:\n  - {name: s, "
                          "link: a, position_m: [0, 0], yaw_deg: 0}\n"),
              HasSubstr("links[1].joint: missing"));
  EXPECT_THAT(parse_error("links:\n  - {name: a, length_m: 1}\nsensors:\n  - {name: s, link: nowhere, position_m: [0, "
                          "0], yaw_deg: 0}\n"),
              HasSubstr("robot.yaml:4: sensors[0].link: no link named 'nowhere'"));
  EXPECT_THAT(
      parse_error(
          "links:\n  - {name: a, length_m: 1}\nsensors:\n  - {name: s, link: a, position_m: [0], yaw_deg: 0}\n"),
      HasSubstr("sensors[0].position_m: expected a list of 2 numbers"));
  EXPECT_THAT(
      parse_error(
          "links:\n  - {name: a, length_m: 1}\nsensors:\n  - {name: s, link: a, position_m: [0, 0], yaw_deg: abc}\n"),
      HasSubstr("sensors[0].yaw_deg: expected a number, got 'abc'"));
  EXPECT_THAT(parse_error("links:\n  - {name: a, length_m: 1}\nsensors:\n"
                          "  - {name: s, link: a, position_m: [0, 0], yaw_deg: 0}\n"
                          "  - {name: t, link: a, position_m: [0, 0], yaw_deg: 0, height_m: 0.1}\n"),
              HasSubstr("robot.yaml:5: sensors[1].height_m"));
  EXPECT_THAT(
      parse_error(
          "links:\n  - {name: a, length_m: 1}\nsensors:\n  - {name: a, link: a, position_m: [0, 0], yaw_deg: 0}\n"),
      HasSubstr("duplicate name 'a'"));
  EXPECT_THAT(parse_error("links: [\n"), HasSubstr("robot.yaml:"));
  EXPECT_THAT(parse_error("links:\n  - {name: a, length_m: 1}\n"), HasSubstr("sensors: expected a non-empty list"));
  try {
    (void)hf::RobotModel::load("/nonexistent/robot.yaml");
    FAIL() << "no error";
  } catch (const hf::RobotModelError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("/nonexistent/robot.yaml: file: robot description '/nonexistent/robot.yaml': cannot open"));
  }
}

TEST(JointStateBuffer, InterpolatesBetweenSamples) {
  hf::JointStateBuffer b({"j1", "j2"});
  const std::vector<std::string> names{"j1", "j2"};
  (void)b.add(ns(1.0), names, std::vector<double>{0.0, 1.0});
  (void)b.add(ns(1.1), names, std::vector<double>{0.2, 1.0});
  const auto q = b.at(ns(1.025));
  ASSERT_TRUE(q.ok()) << q.status.message;
  EXPECT_NEAR(q.positions[0], 0.05, 1e-12);
  EXPECT_NEAR(q.positions[1], 1.0, 1e-12);
  EXPECT_NEAR(q.max_gap_s, 0.025, 1e-9);
}

TEST(JointStateBuffer, StaleStatesAreAnExplicitOutcome) {
  hf::JointStateBuffer b({"j1"}, {.tolerance_s = 0.02, .history_s = 2.0});
  const std::vector<std::string> names{"j1"};
  const auto none = b.at(ns(1.0));
  EXPECT_EQ(none.detail, hf::JointLookupStatus::kNoData);
  EXPECT_EQ(none.status.code, tinyline::common::StatusCode::NotFound);
  EXPECT_THAT(none.status.message, HasSubstr("'j1'"));
  (void)b.add(ns(1.0), names, std::vector<double>{0.3});
  EXPECT_TRUE(b.at(ns(1.015)).ok());  // held within the tolerance
  const auto stale = b.at(ns(1.1));
  EXPECT_EQ(stale.detail, hf::JointLookupStatus::kStale);
  EXPECT_EQ(stale.status.code, tinyline::common::StatusCode::OutOfRange);
  EXPECT_THAT(stale.status.message, HasSubstr("0.100 s older than the scan"));
  const auto early = b.at(ns(0.5));
  EXPECT_EQ(early.detail, hf::JointLookupStatus::kBeforeHistory);
}

TEST(JointStateBuffer, PartialUnknownOutOfOrderAndNonFiniteSamples) {
  hf::JointStateBuffer b({"j1", "j2"});
  // A message with one joint only, one with a foreign joint, one with a NaN.
  auto r = b.add(ns(1.0), std::vector<std::string>{"j1"}, std::vector<double>{0.0});
  EXPECT_EQ(r.used, 1);
  EXPECT_EQ(b.at(ns(1.0)).detail, hf::JointLookupStatus::kNoData);  // j2 still missing
  r = b.add(ns(1.0), std::vector<std::string>{"j2", "gimbal"}, std::vector<double>{0.5, 9.0});
  EXPECT_EQ(r.unknown, 1);
  EXPECT_THAT(r.reason, HasSubstr("1 unknown joint"));
  r = b.add(ns(1.2), std::vector<std::string>{"j1", "j2"}, std::vector<double>{std::nan(""), 0.7});
  EXPECT_EQ(r.non_finite, 1);
  // Out of order: 1.1 arrives after 1.2.
  (void)b.add(ns(1.2), std::vector<std::string>{"j1"}, std::vector<double>{0.4});
  (void)b.add(ns(1.1), std::vector<std::string>{"j1", "j2"}, std::vector<double>{0.1, 0.6});
  const auto q = b.at(ns(1.15));
  ASSERT_TRUE(q.ok()) << q.status.message;
  EXPECT_NEAR(q.positions[0], 0.25, 1e-12);
  EXPECT_NEAR(q.positions[1], 0.65, 1e-12);
  // Mismatched lengths use the common prefix and say so.
  r = b.add(ns(1.3), std::vector<std::string>{"j1", "j2"}, std::vector<double>{0.1});
  EXPECT_EQ(r.used, 1);
  EXPECT_THAT(r.reason, HasSubstr("2 names but 1 positions"));
}

TEST(JointStateBuffer, ForgetsHistoryBeyondItsWindow) {
  hf::JointStateBuffer b({"j1"}, {.tolerance_s = 0.01, .history_s = 0.5});
  for (int i = 0; i <= 20; ++i) (void)b.add(ns(0.1 * i), std::vector<std::string>{"j1"}, std::vector<double>{1.0 * i});
  EXPECT_EQ(b.at(ns(1.0)).detail, hf::JointLookupStatus::kBeforeHistory);
  EXPECT_TRUE(b.at(ns(1.6)).ok());
}
