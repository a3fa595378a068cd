// SPDX-License-Identifier: Apache-2.0
// An independent DDS implementation (the cyclonedds package from PyPI, with
// its own Cyclone DDS and its own CDR code) exchanges sensor_msgs/LaserScan
// with a tinyline bridge, declaring the types the way ROS 2 names them. If
// our topic names, type names or bytes were off, nothing would match or
// decode.
#include <gtest/gtest.h>

#include <unistd.h>

#include <thread>

#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>

#include "bridged_graph.hpp"
#include "child_process.hpp"

using namespace tinyline;
using namespace std::chrono_literals;
using sensor_msgs::msg::LaserScan;
namespace tlt = tinyline::testing;

namespace {

std::string line(const LaserScan& s) {
  auto f = [](float x) { return fmt::format("{:.9g}", static_cast<double>(x)); };
  std::vector<std::string> fl{f(s.angle_min), f(s.angle_max), f(s.angle_increment), f(s.time_increment),
                              f(s.scan_time), f(s.range_min), f(s.range_max)};
  std::vector<std::string> r, in;
  for (float x : s.ranges) r.push_back(f(x));
  for (float x : s.intensities) in.push_back(f(x));
  return fmt::format("SCAN|{}|{}|{}|{}|{}|{}", s.header.stamp.sec, s.header.stamp.nanosec, s.header.frame_id,
                     fmt::join(fl, ","), fmt::join(r, ","), fmt::join(in, ","));
}

LaserScan scan(int i) {
  LaserScan s;
  s.header.stamp.sec = 1700000100 + i;
  s.header.stamp.nanosec = 123456789u + static_cast<std::uint32_t>(i);
  s.header.frame_id = "tiny_laser_" + std::to_string(i);
  s.angle_min = -0.61f;
  s.angle_max = 0.61f;
  s.angle_increment = 1.22f / 255.0f;
  s.time_increment = 0.0f;
  s.scan_time = 1.0f / 60.0f;
  s.range_min = 0.05f;
  s.range_max = 2.0f;
  for (int k = 0; k < 256; ++k) {
    s.ranges.push_back(0.05f + 0.0071f * static_cast<float>(k) + 0.001f * static_cast<float>(i));
    s.intensities.push_back(static_cast<float>((k * 37 + i) % 1000));
  }
  s.ranges[7] = std::numeric_limits<float>::infinity();  // out of range, as ROS encodes it
  return s;
}

/// A graph in this process: its bridge, one node "laser".
struct Graph : tlt::BridgedGraph {
  explicit Graph(const dds::Settings& s) : BridgedGraph(s, "laser") {}
};

/// This test's own domain and tag, in this process and in the Python one.
std::pair<dds::Settings, std::vector<std::string>> settings() {
  dds::Settings s;
  s.domain_id = 1 + static_cast<int>(getpid() % 200);
  s.config = dds::loopback_config(
      fmt::format("py_{}_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name(), getpid()));
  s.process_name = "interop";
  return {s, {fmt::format("ROS_DOMAIN_ID={}", s.domain_id), "CYCLONEDDS_URI=" + s.config}};
}

std::vector<std::string> python(const std::string& mode, const std::string& topic, int n,
                                const std::string& reliability = "reliable") {
  return {TINYLINE_VENV_PYTHON,
          std::string(TINYLINE_SOURCE_DIR) + "/test/dds/ros2_laserscan.py",
          mode,
          topic,
          std::to_string(n),
          reliability};
}

}  // namespace

TEST(Ros2Interop, APythonCycloneDdsSubscriberReceivesOurLaserScans) {
  if (access(TINYLINE_VENV_PYTHON, X_OK) != 0) GTEST_SKIP() << "no test venv at " << TINYLINE_VENV_PYTHON;
  auto [s, env] = settings();
  Graph g(s);
  auto pub = g.node->create_publisher<LaserScan>("/tiny/scan");
  g.run();
  tlt::ChildProcess py(python("sub", "/tiny/scan", 5), env);
  ASSERT_TRUE(py.wait_for_text("READY", 60s)) << py.output();
  const auto w = g.bridge->wait_for_peers({{"/tiny/scan", 1, 0}}, 30s);
  ASSERT_TRUE(w.ok) << w.missing << "\n" << g.sink->dump() << py.output();
  EXPECT_TRUE(g.sink->contains(bus::LogLevel::Info, "remote subscriber in a participant that is not tinyline"));
  std::vector<std::string> sent;
  for (int i = 0; i < 5; ++i) {
    auto m = std::make_unique<LaserScan>(scan(i));
    sent.push_back(line(*m));
    pub->publish(std::move(m));
  }
  const auto st = py.wait_exit(60s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << py.output();
  std::vector<std::string> got;
  for (const auto& l : py.lines())
    if (l.rfind("SCAN|", 0) == 0) got.push_back(l);
  EXPECT_EQ(got, sent);
}

TEST(Ros2Interop, OurSubscriberDecodesLaserScansAPythonPublisherSends) {
  if (access(TINYLINE_VENV_PYTHON, X_OK) != 0) GTEST_SKIP() << "no test venv at " << TINYLINE_VENV_PYTHON;
  auto [s, env] = settings();
  Graph g(s);
  tlt::Inbox<std::string> got(g.signal);
  auto sub = g.node->create_subscription<LaserScan>("/py/scan", bus::QoS::keep_last(50),
                                                    [&](const LaserScan& m) { got.push(line(m)); });
  g.run();
  tlt::ChildProcess py(python("pub", "/py/scan", 4), env);
  const auto st = py.wait_exit(60s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << py.output() << g.sink->dump();
  ASSERT_TRUE(g.signal->wait_for([&] { return got.size() >= 4; }, 10s)) << g.sink->dump();
  std::vector<std::string> sent;
  for (const auto& l : py.lines())
    if (l.rfind("SENT|", 0) == 0) sent.push_back("SCAN" + l.substr(4));
  ASSERT_EQ(sent.size(), 4u) << py.output();
  EXPECT_EQ(got.items(), sent);
  for (const auto& st2 : g.bridge->stats()) EXPECT_EQ(st2.decode_errors, 0u) << st2.topic;
}

TEST(Ros2Interop, Ros2SensorDataAndDefaultProfileSubscribersBothReceiveADriversScans) {
  // The driver publishes LaserScan with QoS::sensor_data(). A ROS 2 node
  // subscribing with SensorDataQoS (best effort) and one with the default
  // profile (reliable) must both match it, as they would a ROS 2 driver.
  if (access(TINYLINE_VENV_PYTHON, X_OK) != 0) GTEST_SKIP() << "no test venv at " << TINYLINE_VENV_PYTHON;
  auto [s, env] = settings();
  Graph g(s);
  auto pub = g.node->create_publisher<LaserScan>("/tiny/laser_scan", bus::QoS::sensor_data());
  g.run();
  tlt::ChildProcess reliable(python("sub", "/tiny/laser_scan", 5, "reliable"), env);
  tlt::ChildProcess best_effort(python("sub", "/tiny/laser_scan", 5, "best_effort"), env);
  ASSERT_TRUE(reliable.wait_for_text("READY", 60s)) << reliable.output();
  ASSERT_TRUE(best_effort.wait_for_text("READY", 60s)) << best_effort.output();
  const auto w = g.bridge->wait_for_peers({{"/tiny/laser_scan", 2, 0}}, 30s);
  ASSERT_TRUE(w.ok) << w.missing << "\n" << g.sink->dump() << reliable.output() << best_effort.output();
  std::vector<std::string> sent;
  for (int i = 0; i < 5; ++i) {
    auto m = std::make_unique<LaserScan>(scan(i));
    sent.push_back(line(*m));
    pub->publish(std::move(m));
  }
  for (auto* py : {&reliable, &best_effort}) {
    const auto st = py->wait_exit(60s);
    ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << py->output();
    std::vector<std::string> got;
    for (const auto& l : py->lines())
      if (l.rfind("SCAN|", 0) == 0) got.push_back(l);
    EXPECT_EQ(got, sent);
  }
  for (const auto& st : g.bridge->stats()) EXPECT_EQ(st.incompatible, 0u) << st.topic;
}
