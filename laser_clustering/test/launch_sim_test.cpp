// The shipped launch files of laser_clustering, run end to end on the
// simulator: the launch file as a user runs it (its nodes, parameters and
// remaps), the simulated sensor on the bus clock, the driver's processing,
// the method, stepped on sim time by the deterministic executor.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include <sim/nodes/register.hpp>
#include <tiny_laser_driver/nodes/register.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/geometry_msgs/point_stamped.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/tinyline_msgs/alignment_result.hpp>
#include <tinyline/msg/tinyline_msgs/pedicel_detection.hpp>

#include "laser_clustering/nodes/register.hpp"

namespace bus = tinyline::bus;
namespace launch = tinyline::launch;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::AlignmentResult;
using tinyline::tinyline_msgs::msg::PedicelDetection;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Launched {
  std::shared_ptr<bus::Context> ctx;
  bus::DeterministicExecutor ex;
  bus::NodeRegistry registry;
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::shared_ptr<bus::Node> io;

  Launched(const std::string& file, std::map<std::string, std::string> args) : ctx(make_ctx()), ex(ctx->clock()) {
    tinyline::sim::register_nodes(registry);
    tinyline::tiny_laser_driver::register_nodes(registry);
    tinyline::laser_clustering::register_nodes(registry);
    ctx->clock().set_sim_time(bus::Time::from_seconds(1000.0));
    launch::LoadOptions o;
    o.share_dir = TINYLINE_SOURCE_DIR;
    o.args = std::move(args);
    const auto plan = launch::load_launch_file(std::string(TINYLINE_SOURCE_DIR) + "/launch/" + file, o);
    nodes = launch::instantiate(plan, registry, ctx);
    bus::NodeOptions io_options;
    io_options.name = "test_io";
    io_options.context = ctx;
    io = std::make_shared<bus::Node>(io_options);
    ex.add_node(io);
    for (const auto& n : nodes) ex.add_node(n);
  }
  static std::shared_ptr<bus::Context> make_ctx() {
    bus::ContextOptions o;
    o.clock = bus::ClockType::Sim;
    o.log_sink = std::make_shared<bus::CaptureSink>();
    return bus::Context::create(o);
  }
  void run_for(double s) { ex.advance_to(ctx->clock().now() + bus::Duration(static_cast<std::int64_t>(s * 1e9))); }
};

}  // namespace

// 5.3.2 end to end: the sweep finds the pitch that squares the laser to the
// wrench's face (minus the mount's pitch) and the arm goes there.
TEST(LaserClusteringLaunch, WrenchAlignFindsTheSquarePitchAndTurnsTheGripperToIt) {
  for (const double mount_deg : {5.0, -7.0}) {
    SCOPED_TRACE(mount_deg);
    Launched l("wrench_align.launch.yaml", {{"mount_pitch_deg", std::to_string(mount_deg)}});
    std::vector<AlignmentResult> aligned;
    std::vector<double> commands, states;
    auto s1 = l.io->create_subscription<AlignmentResult>("/gripper/aligned", bus::QoS::keep_last(10),
                                                         [&](const AlignmentResult& m) { aligned.push_back(m); });
    auto s2 = l.io->create_subscription<JointState>("/gripper/joint_command", bus::QoS::keep_last(100),
                                                    [&](const JointState& m) { commands.push_back(m.position.at(0)); });
    auto s3 = l.io->create_subscription<JointState>("/gripper/joint_states", bus::QoS::keep_last(100),
                                                    [&](const JointState& m) { states.push_back(m.position.at(0)); });
    int results = 0;
    auto s4 = l.io->create_subscription<AlignmentResult>("/gripper/alignment", bus::QoS::keep_last(100),
                                                         [&](const AlignmentResult& m) { results += m.outcome != AlignmentResult::INVALID_INPUT; });
    l.run_for(4.0);
    EXPECT_TRUE(aligned.empty()) << "the sweep (17 pitches x 0.3 s) is not over after 4 s";
    l.run_for(2.0);
    ASSERT_EQ(aligned.size(), 1u);
    const AlignmentResult& a = aligned.front();
    ASSERT_EQ(a.outcome, AlignmentResult::FOUND) << a.reason;
    EXPECT_TRUE(a.refined);
    EXPECT_GE(a.num_samples, 17u) << "usable pitches";
    EXPECT_GE(results, 17 * 10) << "every pitch seen by several scans";
    EXPECT_NEAR(a.best_pitch_rad / kDeg, -mount_deg, 1.0) << "the issue's goal: within 1 degree";
    ASSERT_EQ(commands.size(), 18u) << "17 sweep steps and the aligned pitch";
    EXPECT_NEAR(commands.front() / kDeg, -16.0, 1e-9);
    EXPECT_NEAR(commands[16] / kDeg, 16.0, 1e-9);
    EXPECT_DOUBLE_EQ(commands.back(), a.best_pitch_rad);
    l.run_for(0.1);
    ASSERT_FALSE(states.empty());
    EXPECT_DOUBLE_EQ(states.back(), a.best_pitch_rad) << "the arm is at the aligned pitch";
  }
}

namespace {

struct PedicelRun {
  std::vector<PedicelDetection> detections;
};

PedicelRun run_pedicel_guide(std::map<std::string, std::string> args, double seconds) {
  Launched l("pedicel_guide.launch.yaml", std::move(args));
  PedicelRun r;
  auto sub = l.io->create_subscription<PedicelDetection>("/gripper/pedicel", bus::QoS::keep_last(200),
                                                         [&](const PedicelDetection& m) { r.detections.push_back(m); });
  l.run_for(seconds);
  return r;
}

}  // namespace

// 4.4.2 end to end: the scene's target pedicel (6 mm, 2 cm beside the blade
// throat at 15 cm) with a neighbour 6.5 cm off and a tomato edge in view;
// every scan must say "move 2 cm", with the pedicel's width.
TEST(LaserClusteringLaunch, PedicelGuideTellsTheGripperToMoveTwoCentimetres) {
  const PedicelRun r = run_pedicel_guide({}, 0.5);
  ASSERT_GE(r.detections.size(), 30u);
  int move = 0;
  for (const auto& d : r.detections) {
    if (d.outcome != PedicelDetection::MOVE) continue;
    ++move;
    EXPECT_NEAR(d.lateral_offset_m, 0.02, 0.004) << "the target pedicel is 2 cm beside the throat";
    EXPECT_NEAR(d.position.z, 0.15, 0.02) << "at the throat's depth (the calibration's spread: about 1 cm)";
    EXPECT_NEAR(d.width_m, 0.006, 0.004);
    EXPECT_GT(d.confidence, 0.3);
  }
  EXPECT_GE(move, static_cast<int>(r.detections.size()) * 95 / 100) << "a move in at least 95 % of the scans";
}

// The same scene with the throat on the pedicel: cut here.
TEST(LaserClusteringLaunch, PedicelGuideSaysCutHereWhenThePedicelIsBetweenTheBlades) {
  const PedicelRun r = run_pedicel_guide({{"scissor_centre_x_m", "0.02"}}, 0.5);
  ASSERT_GE(r.detections.size(), 30u);
  int cut = 0;
  for (const auto& d : r.detections) cut += d.outcome == PedicelDetection::CUT_HERE;
  EXPECT_GE(cut, static_cast<int>(r.detections.size()) * 95 / 100);
}

// With the vision's expectation (expected_pedicel) on the neighbour, the
// finder centres the neighbour instead: the expectation replaces the throat.
TEST(LaserClusteringLaunch, PedicelGuideFollowsTheVisionsExpectedPedicel) {
  Launched l("pedicel_guide.launch.yaml", {});
  std::vector<PedicelDetection> detections;
  auto sub = l.io->create_subscription<PedicelDetection>("/gripper/pedicel", bus::QoS::keep_last(200),
                                                         [&](const PedicelDetection& m) { detections.push_back(m); });
  auto pub = l.io->create_publisher<tinyline::geometry_msgs::msg::PointStamped>("/gripper/expected_pedicel");
  auto p = std::make_unique<tinyline::geometry_msgs::msg::PointStamped>();
  p->header.stamp = l.ctx->clock().now().to_msg();
  p->header.frame_id = "gripper_laser";
  p->point.x = -0.04;  // the neighbour is at x = -0.045, z = 0.165
  p->point.z = 0.16;
  pub->publish(std::move(p));
  l.run_for(0.5);
  ASSERT_GE(detections.size(), 30u);
  int on_neighbour = 0;
  for (const auto& d : detections) {
    on_neighbour += d.outcome == PedicelDetection::MOVE && std::abs(d.lateral_offset_m - -0.045) < 0.004;
  }
  EXPECT_GE(on_neighbour, static_cast<int>(detections.size()) * 95 / 100);
}

TEST(LaserClusteringLaunch, SimGripperPitchNeedsItsSceneAndNamesWhatIsWrong) {
  auto ctx = Launched::make_ctx();
  bus::DeterministicExecutor ex(ctx->clock());
  bus::NodeRegistry registry;
  tinyline::laser_clustering::register_nodes(registry);
  bus::NodeOptions o;
  o.name = "arm";
  o.context = ctx;
  try {
    ex.add_node(registry.create("laser_clustering", "sim_gripper_pitch", o));
    ex.spin_until_idle();
    FAIL() << "expected the start to fail";
  } catch (const std::exception& e) {  // the executor wraps it: "node '/arm' failed to start: ..."
    EXPECT_NE(std::string(e.what()).find("'scene' is required"), std::string::npos) << e.what();
  }
  bus::NodeOptions limits = o;
  limits.name = "arm2";
  limits.param("min_pitch_deg", 10.0).param("max_pitch_deg", -10.0);
  EXPECT_THROW((void)registry.create("laser_clustering", "sim_gripper_pitch", limits), bus::ParamError);
}
