// SPDX-License-Identifier: Apache-2.0
// The hydrus_fitting nodes on the bus: built by name, fed JointState and
// LineScan messages (exact planar scenes with Table 3.1 noise), stepped by
// the deterministic executor on sim time (no sleeps).
#include <cmath>
#include <numbers>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include "hydrus_fitting/nodes/circle_fitter_node.hpp"
#include "hydrus_fitting/nodes/register.hpp"
#include "hydrus_fitting/nodes/sequencer_node.hpp"
#include "planar_scene.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace ev = tinyline::hydrus_fitting::eval;
namespace bus = tinyline::bus;
using ::testing::HasSubstr;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::CircleFit;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::visualization_msgs::msg::MarkerArray;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";

// The hydrus_fitting nodes on stepped sim time (bus/testing.hpp).
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&hf::register_nodes}) {}
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    return NodeRig::add("hydrus_fitting", type, std::move(o));
  }
};

std::unique_ptr<JointState> joints_msg(const hf::RobotModel& m, double t_s, double q) {
  auto j = std::make_unique<JointState>();
  j->header.stamp = bus::Time::from_seconds(t_s).to_msg();
  j->name = m.joint_names();
  j->position.assign(m.joint_names().size(), q);
  return j;
}

std::unique_ptr<LineScan> scan_msg(const ev::SyntheticScan& s, double t_s) {
  auto m = std::make_unique<LineScan>();
  m->header.stamp = bus::Time::from_seconds(t_s).to_msg();
  m->header.frame_id = s.sensor;
  for (std::size_t i = 0; i < s.range_m.size(); ++i) {
    m->angles.push_back(static_cast<float>(s.angle_rad[i]));
    const bool valid = std::isfinite(s.range_m[i]);
    m->distance_m.push_back(valid ? static_cast<float>(s.range_m[i]) : std::nanf(""));
    m->status.push_back(valid ? LineScan::STATUS_VALID : LineScan::STATUS_OUT_OF_RANGE);
  }
  return m;
}

}  // namespace

TEST(HydrusFittingNodes, CircleFitterIsRegistered) {
  bus::NodeRegistry r;
  hf::register_nodes(r);
  EXPECT_NE(r.find("hydrus_fitting", "circle_fitter"), nullptr);
}

TEST(HydrusFittingNodes, CircleFitterFusesFourSensorsAndPublishesTheCircle) {
  Harness h;
  bus::NodeOptions o;
  o.name = "fitter";
  o.param("robot_description", kConfig);
  o.remap("scans", "/hydrus/scans").remap("circle", "/hydrus/circle");
  h.add("circle_fitter", o);
  auto& got = h.collect<CircleFit>("/hydrus/circle", bus::QoS::keep_last(20));
  auto& markers = h.collect<MarkerArray>("markers", bus::QoS::keep_last(20));
  auto scans = h.io->create_publisher<LineScan>("/hydrus/scans");
  auto joints = h.io->create_publisher<JointState>("joint_states");

  const auto model = hf::RobotModel::load(kConfig);
  const double q = 60.0 * kPi / 180.0;
  const hf::Circle truth{{0.25, 0.433}, 0.15};
  tinyline::common::SplitMixRandom rng(7);
  const auto s = ev::scan_all(model, {q, q, q}, {{truth}, {}, true}, {}, rng);
  joints->publish(joints_msg(model, 1.0, q));
  for (std::size_t k = 0; k < s.size(); ++k) scans->publish(scan_msg(s[k], 1.0 + 0.004 * static_cast<double>(k)));
  h.ex.spin_until_idle();

  ASSERT_EQ(got.size(), 4u);  // one estimate per scan
  const auto& last = *got.back();
  EXPECT_EQ(last.status, CircleFit::STATUS_OK) << last.reason;
  EXPECT_EQ(last.scans, 4u);
  EXPECT_EQ(last.header.frame_id, "base");
  EXPECT_NEAR(last.centre.x, 0.25, 0.005);
  EXPECT_NEAR(last.centre.y, 0.433, 0.005);
  EXPECT_NEAR(last.radius_m, 0.15, 0.005);
  EXPECT_GT(last.covariance[0], 0.0);
  EXPECT_GT(last.inliers, 300u);
  ASSERT_FALSE(markers.empty());
  ASSERT_EQ(markers.back()->markers.size(), 3u);  // cylinder, points, links
  EXPECT_EQ(markers.back()->markers[0].type, tinyline::visualization_msgs::msg::Marker::CYLINDER);
  EXPECT_NEAR(markers.back()->markers[0].scale.x, 2 * last.radius_m, 1e-12);
}

TEST(HydrusFittingNodes, CircleFitterReportsUnknownSensorsAndStaleJoints) {
  Harness h;
  bus::NodeOptions o;
  o.name = "fitter";
  o.param("robot_description", kConfig);
  auto node = std::dynamic_pointer_cast<hf::CircleFitterNode>(h.add("circle_fitter", o));
  auto& got = h.collect<CircleFit>("circle", bus::QoS::keep_last(20));
  auto scans = h.io->create_publisher<LineScan>("scans");
  auto joints = h.io->create_publisher<JointState>("joint_states");
  const auto model = hf::RobotModel::load(kConfig);
  tinyline::common::SplitMixRandom rng(1);
  auto s = ev::scan_all(model, {1.0, 1.0, 1.0}, {{{{0.25, 0.43}, 0.15}}, {}, true}, {}, rng);
  // A sensor the description does not know: ignored, said once, never a crash.
  s[0].sensor = "laser_on_the_tail";
  scans->publish(scan_msg(s[0], 1.0));
  scans->publish(scan_msg(s[0], 1.1));
  h.ex.spin_until_idle();
  EXPECT_TRUE(got.empty());
  EXPECT_EQ(node->unknown_sensors().at("laser_on_the_tail"), 2u);
  int errors = 0;
  for (const auto& r : h.log->records()) errors += r.text.find("'laser_on_the_tail'") != std::string::npos;
  EXPECT_EQ(errors, 1);
  // Joint states a second older than the scan: the estimate says why.
  joints->publish(joints_msg(model, 1.0, 1.0));
  scans->publish(scan_msg(s[1], 2.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_NE(got[0]->status, CircleFit::STATUS_OK);
  EXPECT_THAT(got[0]->reason, HasSubstr("older than the scan"));
}

TEST(HydrusFittingNodes, CircleFitterMovesScansByTheBasePose) {
  // The base flies along +y at 0.125 m/s turning at 0.2 rad/s past a
  // cylinder that stands still; the four scans are 30 ms apart.
  const auto model = hf::RobotModel::load(kConfig);
  const double q = 60.0 * kPi / 180.0;
  auto base = [](double t) {
    return Eigen::Isometry2d(Eigen::Translation2d(0.0, 0.125 * t) * Eigen::Rotation2Dd(0.2 * (t - 1.0)));
  };
  const Eigen::Vector2d fixed = base(1.09) * Eigen::Vector2d(0.25, 0.433);
  const Eigen::Vector2d truth_now = base(1.09).inverse() * fixed;
  std::vector<ev::SyntheticScan> s;
  tinyline::common::SplitMixRandom rng(1);
  ev::SyntheticScanParams exact;
  exact.noise_scale = 0.0;
  for (std::size_t k = 0; k < 4; ++k) {
    const double t = 1.0 + 0.03 * static_cast<double>(k);
    const ev::PlanarWorld world{{hf::Circle{base(t).inverse() * fixed, 0.15}}, {}, false};
    s.push_back(ev::scan_all(model, {q, q, q}, world, exact, rng)[k]);
  }
  auto run = [&](bool with_poses) {
    Harness h;
    bus::NodeOptions o;
    o.name = "fitter";
    o.param("robot_description", kConfig);
    h.add("circle_fitter", o);
    auto& got = h.collect<CircleFit>("circle", bus::QoS::keep_last(20));
    auto scans = h.io->create_publisher<LineScan>("scans");
    auto joints = h.io->create_publisher<JointState>("joint_states");
    auto poses = h.io->create_publisher<tinyline::geometry_msgs::msg::PoseStamped>("base_pose");
    for (int i = 0; i <= 30; ++i) {
      const double t = 0.9 + 0.01 * i;
      joints->publish(joints_msg(model, t, q));
      if (!with_poses) continue;
      auto p = std::make_unique<tinyline::geometry_msgs::msg::PoseStamped>();
      p->header.stamp = bus::Time::from_seconds(t).to_msg();
      p->pose.position.x = base(t).translation().x();
      p->pose.position.y = base(t).translation().y();
      p->pose.orientation.z = std::sin(0.1 * (t - 1.0));  // yaw 0.2 (t - 1)
      p->pose.orientation.w = std::cos(0.1 * (t - 1.0));
      poses->publish(std::move(p));
    }
    h.ex.spin_until_idle();
    for (std::size_t k = 0; k < s.size(); ++k) scans->publish(scan_msg(s[k], 1.0 + 0.03 * static_cast<double>(k)));
    h.ex.spin_until_idle();
    EXPECT_EQ(got.size(), 4u);
    return got.empty() ? 1.0 : std::hypot(got.back()->centre.x - truth_now.x(), got.back()->centre.y - truth_now.y());
  };
  const double smeared = run(false);
  const double moved = run(true);
  EXPECT_GT(smeared, 0.003);
  EXPECT_LT(moved, 0.0005) << "without base poses " << smeared;
}

TEST(HydrusFittingNodes, CircleFitterNeedsAValidRobotDescription) {
  {
    Harness h;
    bus::NodeOptions o;
    o.name = "fitter";
    EXPECT_THROW(h.add("circle_fitter", o), bus::ParamError);  // robot_description is required
  }
  Harness h;
  bus::NodeOptions o;
  o.name = "fitter";
  o.param("robot_description", std::string("/nonexistent/hydrus.yaml"));
  h.add("circle_fitter", o);
  try {
    h.ex.spin_until_idle();
    FAIL() << "started without a robot description";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("/nonexistent/hydrus.yaml: file: robot description '/nonexistent/hydrus.yaml': cannot open"));
  }
}

namespace {

using tinyline::diagnostic_msgs::msg::DiagnosticArray;
using tinyline::tinyline_msgs::msg::LaserCommand;

std::string value_of(const DiagnosticArray& d, const std::string& key) {
  for (const auto& s : d.status)
    for (const auto& kv : s.values)
      if (kv.key == key) return kv.value;
  return "";
}

struct SequencerRig {
  Harness h;
  hf::RobotModel model = hf::RobotModel::load(kConfig);
  std::vector<std::shared_ptr<const LaserCommand>> cmds;
  std::vector<std::shared_ptr<const DiagnosticArray>> diags;
  std::shared_ptr<bus::Subscription<LaserCommand>> cmd_sub;
  std::shared_ptr<bus::Subscription<DiagnosticArray>> diag_sub;
  std::shared_ptr<bus::Publisher<JointState>> joints;
  std::shared_ptr<bus::Publisher<CircleFit>> circle;
  std::shared_ptr<hf::SequencerNode> node;

  explicit SequencerRig(const std::string& mode) {
    bus::NodeOptions o;
    o.name = "sequencer";
    o.param("robot_description", kConfig).param("mode", mode).param("set_period_s", 0.018).param("guard_s", 0.002);
    o.param("object_max_age_s", 10.0);
    node = std::dynamic_pointer_cast<hf::SequencerNode>(h.add("sequencer", o));
    cmd_sub = h.io->create_subscription<LaserCommand>(
        "laser_command", bus::QoS::keep_last(1000),
        [this](const std::shared_ptr<const LaserCommand>& m) { cmds.push_back(m); });
    diag_sub = h.io->create_subscription<DiagnosticArray>(
        "diagnostics", bus::QoS::keep_last(100),
        [this](const std::shared_ptr<const DiagnosticArray>& m) { diags.push_back(m); });
    joints = h.io->create_publisher<JointState>("joint_states");
    circle = h.io->create_publisher<CircleFit>("circle");
    advance(0.0);  // starts the sim clock and the node
  }
  void advance(double t_s) { h.ex.advance_to(bus::Time::from_seconds(t_s)); }
};

}  // namespace

TEST(HydrusFittingNodes, SequencerColoursTheSquareIntoTwoSlots) {
  SequencerRig r("colouring");
  // The square around a 12 cm cylinder, and the object estimate.
  for (int k = 0; k <= 40; ++k) r.joints->publish(joints_msg(r.model, 0.05 * k, kPi / 2));
  auto c = std::make_unique<CircleFit>();
  c->header.stamp = bus::Time::from_seconds(0.0).to_msg();
  c->status = CircleFit::STATUS_OK;
  c->centre.x = 0.25;
  c->centre.y = 0.25;
  c->radius_m = 0.12;
  r.circle->publish(std::move(c));
  r.h.ex.spin_until_idle();
  r.advance(0.2);  // ten 20 ms slots
  ASSERT_GE(r.cmds.size(), 9u);
  EXPECT_EQ(r.node->schedule().name, "colouring");
  ASSERT_EQ(r.node->schedule().slot_count(), 2);
  // Opposite sensors together, alternating: {laser1, laser3} then {laser2, laser4}.
  hf::Sequencer check(r.model);
  (void)check.update(std::vector<double>(3, kPi / 2), hf::Circle{{0.25, 0.25}, 0.12});
  int on_count[4] = {0, 0, 0, 0};
  for (const auto& m : r.cmds) {
    ASSERT_EQ(m->sensors.size(), 4u);
    ASSERT_EQ(m->laser_on.size(), 4u);
    for (int i = 0; i < 4; ++i) {
      on_count[i] += m->laser_on[static_cast<std::size_t>(i)];
      for (int j = i + 1; j < 4; ++j) {
        EXPECT_FALSE(m->laser_on[static_cast<std::size_t>(i)] && m->laser_on[static_cast<std::size_t>(j)] &&
                     check.graph().conflict(i, j))
            << "sensors " << i << " and " << j << " emit together but conflict";
      }
    }
    EXPECT_EQ(m->active_slots.size(), 2u);
  }
  // Every sensor emits in half of the slots (twice the thesis's quarter).
  const auto slots = static_cast<int>(r.cmds.size());
  for (const int k : on_count) EXPECT_NEAR(k, slots / 2.0, 1.0);
  r.advance(1.01);
  ASSERT_FALSE(r.diags.empty());
  EXPECT_EQ(value_of(*r.diags.back(), "laser1.rate_hz"), "25.00");
  EXPECT_EQ(value_of(*r.diags.back(), "laser1.thesis_rate_hz"), "12.50");
}

TEST(HydrusFittingNodes, SequencerFallsBackToTimeSlicingWithoutJoints) {
  SequencerRig r("colouring");
  r.advance(0.1);
  ASSERT_GE(r.cmds.size(), 4u);
  for (const auto& m : r.cmds) {
    int on = 0;
    for (const bool b : m->laser_on) on += b;
    EXPECT_EQ(on, 1);  // one sensor per slot: always safe
  }
  int warnings = 0;
  for (const auto& rec : r.h.log->records()) warnings += rec.text.find("one sensor per slot") != std::string::npos;
  EXPECT_EQ(warnings, 1);
}

TEST(HydrusFittingNodes, SequencerModesTimeSlicingAndAllOn) {
  {
    SequencerRig r("time_slicing");
    r.joints->publish(joints_msg(r.model, 0.0, kPi / 2));
    r.advance(0.16);  // eight slots: each sensor twice, in order
    ASSERT_GE(r.cmds.size(), 8u);
    for (std::size_t k = 0; k < 8; ++k) {
      for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(r.cmds[k]->laser_on[i], i == k % 4) << k;
    }
  }
  SequencerRig r("all_on");
  r.advance(0.1);
  ASSERT_FALSE(r.cmds.empty());
  for (const auto& m : r.cmds)
    for (const bool b : m->laser_on) EXPECT_TRUE(b);
}

TEST(HydrusFittingNodes, SequencerTakesASensorThatIgnoresLaserOffAsAlwaysEmitting) {
  // laser2 runs a firmware that ignores the laser command: its scans keep
  // coming, read out long after it was told off. The sequencer stops giving
  // it a slot of its own and keeps it on everywhere.
  SequencerRig r("time_slicing");
  r.joints->publish(joints_msg(r.model, 0.0, kPi / 2));
  auto scans = r.h.io->create_publisher<tinyline::tinyline_msgs::msg::LineScan>("scans");
  for (int k = 1; k <= 60; ++k) {
    const double t = 0.02 * k;
    r.advance(t);
    auto m = std::make_unique<tinyline::tinyline_msgs::msg::LineScan>();
    m->header.stamp = bus::Time::from_seconds(t).to_msg();
    m->header.frame_id = "laser2";
    scans->publish(std::move(m));
    r.h.ex.spin_until_idle();
  }
  const std::size_t before = r.cmds.size();
  r.advance(1.6);
  ASSERT_GT(r.cmds.size(), before + 6);
  for (std::size_t k = before; k < r.cmds.size(); ++k) {
    const auto& m = *r.cmds[k];
    EXPECT_TRUE(m.laser_on[1]) << k;  // always on
    int others = 0;
    for (std::size_t i : {0u, 2u, 3u}) others += m.laser_on[i];
    EXPECT_EQ(others, 1) << k;  // the others still one per slot; no slot for laser2 alone
  }
  r.advance(2.01);
  ASSERT_FALSE(r.diags.empty());
  EXPECT_EQ(value_of(*r.diags.back(), "laser2.obeys_laser_off").rfind("no (", 0), 0u);
  EXPECT_EQ(value_of(*r.diags.back(), "laser1.obeys_laser_off"), "yes or untested");
}
