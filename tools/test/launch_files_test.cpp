// SPDX-License-Identifier: Apache-2.0
// Every launch file the project ships loads and builds with the real node
// registry: no unknown key, node type or parameter can rot in them.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <tinyline/bus/executor.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/tf2_msgs/tf_message.hpp>
#include <tinyline/tools/command.hpp>

using namespace tinyline;
namespace fs = std::filesystem;

TEST(ShippedLaunchFiles, EveryOneLoadsAndBuildsItsNodes) {
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(TINYLINE_SOURCE_DIR) / "launch")) {
    if (e.path().extension() != ".yaml") continue;
    SCOPED_TRACE(e.path().string());
    launch::LoadOptions o;
    o.share_dir = TINYLINE_SOURCE_DIR;
    bus::ContextOptions co;
    co.clock = bus::ClockType::Sim;
    co.log_sink = std::make_shared<bus::CaptureSink>();
    try {
      const auto plan = launch::load_launch_file(e.path().string(), o);
      std::set<std::string> processes;
      for (const auto& n : plan.nodes) processes.insert(n.process);
      std::size_t built = 0;
      for (const auto& p : processes)
        built += launch::instantiate(plan, tools::node_registry(), bus::Context::create(co), p).size();
      EXPECT_EQ(built, plan.nodes.size());
      EXPECT_GT(built, 0u);
    } catch (const std::exception& ex) {
      ADD_FAILURE() << ex.what();
    }
    ++files;
  }
  EXPECT_GE(files, 1);
}

TEST(ShippedLaunchFiles, AnUnknownParameterInAShippedStyleFileIsCaught) {
  const std::string yaml = "launch:\n- node: {pkg: tinyline, exec: pulse, param: [{name: rate, value: 3}]}\n";
  const auto plan = launch::load_launch_string(yaml, "probe.yaml");
  bus::ContextOptions co;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  EXPECT_THROW(launch::instantiate(plan, tools::node_registry(), bus::Context::create(co)), launch::LaunchError);
}

// tinyline/echo writes every message to a stream nobody may be reading: a
// transport's delivery thread must never run its callback (it would hold up
// every topic of the process while the stream is full).
TEST(UtilityNodes, EchoNeverRunsOnATransportsDeliveryThread) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  bus::NodeOptions o;
  o.name = "echo";
  o.context = bus::Context::create(co);
  const auto echo = tools::node_registry().create("tinyline", "echo", o);
  EXPECT_FALSE(echo->callback_group()->accepts_inline());
}

namespace {

/// What building the nodes of `yaml` says: "no error" or the error's text.
std::string frames_error(const std::string& yaml) {
  bus::ContextOptions co;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  try {
    const auto plan = launch::load_launch_string(yaml, "frames.yaml");
    (void)launch::instantiate(plan, tools::node_registry(), bus::Context::create(co));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

std::string frame(const std::string& args) {
  return "launch:\n- node:\n    pkg: tf2_ros\n    exec: static_transform_publisher\n    args: \"" + args + "\"\n";
}

}  // namespace

TEST(StaticFrames, AFrameDeclaredAsInRos2IsPublishedLatchedOnTfStaticAndGoesOnDds) {
  const auto plan = launch::load_launch_string(
      frame("--x 0.1 --yaw 1.5707963267948966 --frame-id base_link --child-frame-id laser"), "frames.yaml");
  ASSERT_EQ(plan.nodes.size(), 1u);
  EXPECT_TRUE(plan.nodes[0].dds);  // frames are for the ROS 2 graph
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  auto ctx = bus::Context::create(co);
  auto nodes = launch::instantiate(plan, tools::node_registry(), ctx);
  bus::NodeOptions no;
  no.name = "listener";
  no.context = ctx;
  auto listener = std::make_shared<bus::Node>(no);
  std::vector<tf2_msgs::msg::TFMessage> got;
  auto sub = listener->create_subscription<tf2_msgs::msg::TFMessage>(
      "/tf_static", bus::QoS::keep_last(100).latched(), [&](const tf2_msgs::msg::TFMessage& m) { got.push_back(m); });
  bus::DeterministicExecutor ex(ctx->clock());
  for (auto& n : nodes) ex.add_node(n);
  ex.add_node(listener);
  ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  ASSERT_EQ(got[0].transforms.size(), 1u);
  const auto& t = got[0].transforms[0];
  EXPECT_EQ(t.header.frame_id, "base_link");
  EXPECT_EQ(t.child_frame_id, "laser");
  EXPECT_DOUBLE_EQ(t.transform.translation.x, 0.1);
  EXPECT_NEAR(t.transform.rotation.z, std::sqrt(0.5), 1e-12);  // a quarter turn about z
  EXPECT_NEAR(t.transform.rotation.w, std::sqrt(0.5), 1e-12);
}

TEST(StaticFrames, AWrongFrameDeclarationStopsTheLaunchAtItsLineWithTheReason) {
  EXPECT_EQ(frames_error(frame("--frame-id base_link --child-frame-id laser")), "no error");
  const std::string missing = frames_error(frame("--frame-id base_link"));
  EXPECT_NE(missing.find("frames.yaml:3:5: "), std::string::npos) << missing;  // the node entry
  EXPECT_NE(missing.find("parameter 'child_frame_id' is required"), std::string::npos) << missing;
  EXPECT_EQ(frames_error(frame("--frame-id a --child-frame-id a")),
            "frames.yaml:5:11: node '/static_transform_publisher': frame 'a' cannot be its own parent");
  EXPECT_NE(frames_error(frame("--yaw 1 --qw 1 --frame-id a --child-frame-id b")).find("not both"), std::string::npos);
  EXPECT_NE(frames_error(frame("--qw 0 --frame-id a --child-frame-id b")).find("has no direction"), std::string::npos);
  // ROS 2's flags only: an unknown one names itself and the known ones.
  const std::string unknown = frames_error(frame("--xx 1 --frame-id a --child-frame-id b"));
  EXPECT_NE(unknown.find("frames.yaml:5:11"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("xx"), std::string::npos) << unknown;
  // Positional arguments (ROS 2's deprecated form) and a flag without a value.
  EXPECT_EQ(frames_error(frame("0 0 0 0 0 0 a b")),
            "frames.yaml:5:11: args: expected a --flag before '0' (positional arguments are not supported; give each "
            "value as --flag value)");
  EXPECT_EQ(frames_error(frame("--frame-id a --child-frame-id")),
            "frames.yaml:5:11: args: --child-frame-id needs a value");
}
