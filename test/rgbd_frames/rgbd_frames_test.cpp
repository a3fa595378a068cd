// SPDX-License-Identifier: Apache-2.0
// Run on your own frames: the simulated camera's cloud, recorded by the
// shipped harvesting launch file, is written as a folder of RGB-D frames by
// an independent tool (write_frames.py: the mcap packages, numpy and Pillow),
// and launch/tomato_frames.launch.yaml plays that folder to the same
// detector. Same scene, same pose: the same tomatoes, pedicels and pick
// order, up to what 1 mm depth steps move (the PNG holds whole millimetres).
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <laser_clustering/nodes/register.hpp>
#include <sim/nodes/register.hpp>
#include <tinyline/bag/register.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>
#include <tinyline/bus/testing.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/tinyline_msgs/tomato_estimates.hpp>
#include <tomato_reasoning/eval/scenario.hpp>
#include <tomato_reasoning/nodes/register.hpp>
#include <tomato_reasoning/sim/register.hpp>

namespace bus = tinyline::bus;
namespace launch = tinyline::launch;
namespace fs = std::filesystem;
using tinyline::tinyline_msgs::msg::TomatoEstimates;

namespace {

/// A shipped launch file instantiated on sim time, stepped by the test.
struct Launched {
  std::shared_ptr<bus::CaptureSink> log = std::make_shared<bus::CaptureSink>();
  std::shared_ptr<bus::Context> ctx;
  bus::DeterministicExecutor ex;
  bus::NodeRegistry registry;
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::shared_ptr<bus::Node> io;

  Launched(const std::string& file, std::map<std::string, std::string> args) : ctx(make_ctx(log)), ex(ctx->clock()) {
    tinyline::sim::register_nodes(registry);
    tinyline::tomato_reasoning::register_nodes(registry);
    tinyline::tomato_reasoning::register_sim_nodes(registry);
    tinyline::laser_clustering::register_nodes(registry);
    tinyline::bag::register_nodes(registry);
    ctx->clock().set_sim_time(bus::Time::from_seconds(1000.0));
    launch::LoadOptions o;
    o.share_dir = TINYLINE_SOURCE_DIR;
    o.args = std::move(args);
    nodes = launch::instantiate(launch::load_launch_file(std::string(TINYLINE_SOURCE_DIR) + "/launch/" + file, o),
                                registry, ctx);
    bus::NodeOptions io_options;
    io_options.name = "test_io";
    io_options.context = ctx;
    io = std::make_shared<bus::Node>(io_options);
    ex.add_node(io);
    for (const auto& n : nodes) ex.add_node(n);
  }
  static std::shared_ptr<bus::Context> make_ctx(std::shared_ptr<bus::CaptureSink> sink) {
    bus::ContextOptions o;
    o.clock = bus::ClockType::Sim;
    o.log_sink = std::move(sink);
    return bus::Context::create(o);
  }
  std::vector<std::shared_ptr<const TomatoEstimates>>& collect_tomatoes() {
    sub = io->create_subscription<TomatoEstimates>(
        "/tomatoes", bus::QoS::keep_last(100),
        [this](const std::shared_ptr<const TomatoEstimates>& m) { got.push_back(m); });
    return got;
  }
  void run_for(double s) { ex.advance_to(ctx->clock().now() + bus::Duration(static_cast<std::int64_t>(s * 1e9))); }
  /// Ends the graph as `tinyline launch` does: the recorder closes its file.
  void stop() {
    for (const auto& n : nodes) n->on_stop();
  }
  std::vector<std::shared_ptr<const TomatoEstimates>> got;
  std::shared_ptr<bus::Subscription<TomatoEstimates>> sub;
};

int run(const std::string& cmd, std::string& output) {
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (p == nullptr) return -1;
  char buf[4096];
  while (std::fgets(buf, sizeof(buf), p) != nullptr) output += buf;
  const int rc = ::pclose(p);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

Eigen::Vector3d eig(const auto& p) { return {p.x, p.y, p.z}; }

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace

TEST(RgbdFrames, FramesWrittenFromTheSimulatedCameraGiveTheLiveCamerasTomatoes) {
  ASSERT_TRUE(fs::exists(TINYLINE_VENV_PYTHON)) << "the test virtual env is missing: run scripts/bootstrap";
  bus::testing::TempDir dir;

  // The live camera (class B seed 4, one view) and its detections, recorded.
  Launched live("tomato_harvest.launch.yaml", {{"views", "1"}, {"bag", dir / "live.mcap"}});
  auto& live_tomatoes = live.collect_tomatoes();
  live.run_for(2.5);  // the camera's first frame is at 2 s (0.5 Hz)
  live.stop();
  ASSERT_EQ(live_tomatoes.size(), 1u);
  const TomatoEstimates& want = *live_tomatoes[0];
  ASSERT_GE(want.tomatoes.size(), 3u) << want.stage << ": " << want.reason;

  // The recorded cloud as RGB-D files, by a tool that shares no code with ours.
  const auto k = tinyline::tomato_reasoning::eval::ScenarioOptions{}.camera.intrinsics;
  std::string out;
  const std::string cmd = std::string(TINYLINE_VENV_PYTHON) + " " + TINYLINE_SOURCE_DIR +
                          "/test/rgbd_frames/write_frames.py " + dir / "live.mcap" + " " + dir / "frames" + " --fx " +
                          std::to_string(k.fx) + " --fy " + std::to_string(k.fy) + " --cx " + std::to_string(k.cx) +
                          " --cy " + std::to_string(k.cy);
  ASSERT_EQ(run(cmd, out), 0) << out;
  ASSERT_TRUE(fs::exists(dir / "frames/depth/000000.png")) << out;

  // The same frames without the bus (tomato_frames): the same pick order, and
  // an annotated copy of the colour image.
  std::string printed;
  ASSERT_EQ(run(std::string(TOMATO_FRAMES_PROGRAM) + " " + dir / "frames" + " --out " + dir / "annotated", printed), 0)
      << printed;
  std::string order;
  for (int i : want.pick_order) order += (order.empty() ? "" : " ") + std::to_string(i);
  EXPECT_THAT(printed, ::testing::HasSubstr("000000: " + std::to_string(want.tomatoes.size()) +
                                            " tomatoes, pick order [" + order + "]"));
  const cv::Mat colour = cv::imread(dir / "frames/rgb/000000.png"),
                annotated = cv::imread(dir / "annotated/000000.png");
  ASSERT_EQ(annotated.size(), colour.size());
  EXPECT_GT(cv::countNonZero(cv::Mat(colour != annotated).reshape(1)), 1000);  // drawn on, not a copy

  // The folder played to the same detector.
  Launched played("tomato_frames.launch.yaml", {{"folder", dir / "frames"}, {"bag", dir / "frames.mcap"}});
  auto& got = played.collect_tomatoes();
  played.run_for(3.5);
  played.stop();
  ASSERT_EQ(got.size(), 1u);  // one frame, played once
  const TomatoEstimates& have = *got[0];
  ASSERT_EQ(have.tomatoes.size(), want.tomatoes.size()) << have.stage << ": " << have.reason;
  EXPECT_EQ(have.pick_order, want.pick_order);
  EXPECT_TRUE(played.log->contains(bus::LogLevel::Info, "tomatoes, pick order ["));
  EXPECT_EQ(have.header.frame_id, want.header.frame_id);
  for (std::size_t i = 0; i < want.tomatoes.size(); ++i) {
    const auto &a = have.tomatoes[i], &b = want.tomatoes[i];
    SCOPED_TRACE("tomato " + std::to_string(i));
    EXPECT_LT((eig(a.centre) - eig(b.centre)).norm(), 0.001);
    EXPECT_NEAR(a.radius_m, b.radius_m, 0.001);
    EXPECT_EQ(a.contacts, b.contacts);
    EXPECT_LT(angle_deg(eig(a.pedicel_direction), eig(b.pedicel_direction)), 2.0);
    EXPECT_LT((eig(a.cut_point) - eig(b.cut_point)).norm(), 0.0015);
    std::printf("tomato %zu: centre moved %.2f mm, radius %.2f mm, pedicel %.2f deg, cut point %.2f mm\n", i,
                1e3 * (eig(a.centre) - eig(b.centre)).norm(), 1e3 * std::abs(a.radius_m - b.radius_m),
                angle_deg(eig(a.pedicel_direction), eig(b.pedicel_direction)),
                1e3 * (eig(a.cut_point) - eig(b.cut_point)).norm());
  }
}
