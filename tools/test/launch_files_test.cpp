// SPDX-License-Identifier: Apache-2.0
// Every launch file the project ships loads and builds with the real node
// registry: no unknown key, node type or parameter can rot in them.
#include <gtest/gtest.h>

#include <filesystem>

#include <tinyline/launch/launch.hpp>
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
