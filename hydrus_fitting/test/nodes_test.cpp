// The hydrus_fitting nodes on the bus: built by name, fed JointState and
// LineScan messages (exact planar scenes with Table 3.1 noise), stepped by
// the deterministic executor on sim time (no sleeps).
#include <cmath>
#include <numbers>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>

#include "hydrus_fitting/nodes/circle_fitter_node.hpp"
#include "hydrus_fitting/nodes/register.hpp"
#include "planar_scene.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace ev = tinyline::hydrus_fitting::eval;
namespace bus = tinyline::bus;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::CircleFit;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::visualization_msgs::msg::MarkerArray;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";

struct Harness {
  std::shared_ptr<bus::CaptureSink> log = std::make_shared<bus::CaptureSink>();  // before ctx: it uses it
  std::shared_ptr<bus::Context> ctx;
  bus::DeterministicExecutor ex;
  bus::NodeRegistry registry;
  std::shared_ptr<bus::Node> io;

  Harness() : ctx(make_ctx(log)), ex(ctx->clock()) {
    hf::register_nodes(registry);
    bus::NodeOptions o;
    o.name = "io";
    o.context = ctx;
    io = std::make_shared<bus::Node>(o);
    ex.add_node(io);
  }
  static std::shared_ptr<bus::Context> make_ctx(std::shared_ptr<bus::CaptureSink> sink) {
    bus::ContextOptions o;
    o.clock = bus::ClockType::Sim;
    o.log_sink = std::move(sink);
    return bus::Context::create(o);
  }
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    o.context = ctx;
    auto n = registry.create("hydrus_fitting", type, std::move(o));
    ex.add_node(n);
    return n;
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
  std::vector<std::shared_ptr<const CircleFit>> got;
  std::vector<std::shared_ptr<const MarkerArray>> markers;
  auto sub = h.io->create_subscription<CircleFit>("/hydrus/circle", bus::QoS::keep_last(20),
                                                  [&](const std::shared_ptr<const CircleFit>& m) { got.push_back(m); });
  auto msub = h.io->create_subscription<MarkerArray>(
      "markers", bus::QoS::keep_last(20), [&](const std::shared_ptr<const MarkerArray>& m) { markers.push_back(m); });
  auto scans = h.io->create_publisher<LineScan>("/hydrus/scans");
  auto joints = h.io->create_publisher<JointState>("joint_states");

  const auto model = hf::RobotModel::load(kConfig);
  const double q = 60.0 * kPi / 180.0;
  const hf::Circle truth{{0.25, 0.433}, 0.15};
  hf::detail::SplitMix64 rng(7);
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
  std::vector<std::shared_ptr<const CircleFit>> got;
  auto sub = h.io->create_subscription<CircleFit>("circle", bus::QoS::keep_last(20),
                                                  [&](const std::shared_ptr<const CircleFit>& m) { got.push_back(m); });
  auto scans = h.io->create_publisher<LineScan>("scans");
  auto joints = h.io->create_publisher<JointState>("joint_states");
  const auto model = hf::RobotModel::load(kConfig);
  hf::detail::SplitMix64 rng(1);
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
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/hydrus.yaml: file: cannot open"));
  }
}
