// SPDX-License-Identifier: Apache-2.0
// A bag of the driver's output replays to identical messages: the recorder's
// file holds, byte for byte, what the driver published; and its raw scans,
// replayed through the raw processor with the same calibration, give back the
// driver's LineScans and LaserScans byte for byte.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <map>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bag/replay.hpp>
#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/nodes/raw_processor.hpp>

#include "synthetic_raw_set.hpp"
#include <tinyline/bus/testing.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace tt = tinyline::tiny_laser_driver::testing;
namespace bus = tinyline::bus;
namespace bag = tinyline::bag;
namespace io = tl::io;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;
using tinyline::sensor_msgs::msg::LaserScan;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::RawScan;

namespace {

// A varied set: ratio, light and temperature change with the seed and pixel,
// some pixels saturate at the top read-outs, some are too dark.
Bytes make_set(int seed) { return tt::varied_set(seed, static_cast<std::uint16_t>(400 + seed % 50)); }

template <class T>
Bytes cdr(const T& m) {
  Bytes out;
  tinyline::msg::type_support<T>().serialize(&m, out);
  return out;
}

using TempDir = tinyline::bus::testing::TempDir;

}  // namespace

TEST(LaserDriverReplay, ARecordedBagReplaysToIdenticalMessages) {
  TempDir tmp;
  const std::string calib_path = (tmp.path / "k.yaml").string();
  tl::load_calibration("public:K").save(calib_path);  // a real sensor's calibration, through its YAML
  const std::string bag_path = (tmp.path / "driver.mcap").string();

  // ---- live: the driver on an in-memory device, recorded.
  std::map<std::string, std::vector<Bytes>> live;
  {
    bus::ContextOptions co;
    co.clock = bus::ClockType::Sim;
    co.log_sink = std::make_shared<bus::CaptureSink>();
    auto ctx = bus::Context::create(co);
    ctx->clock().set_sim_time(bus::Time::from_seconds(1000.0));
    bus::DeterministicExecutor ex(ctx->clock());
    auto link = io::MemoryLink::create("replay");
    io::register_memory_link("replay", link);
    bus::NodeOptions o;
    o.context = ctx;
    o.name = "driver";
    o.ns = "/tiny";
    o.param("port", std::string("mem:replay")).param("calibration", calib_path).param("threaded", false);
    auto driver = std::make_shared<tl::LaserDriver>(o);
    bag::RecorderOptions ro;
    ro.path = bag_path;
    ro.topics = {"/tiny/raw", "/tiny/scan", "/tiny/laser_scan"};
    bus::NodeOptions rec;
    rec.context = ctx;
    rec.name = "recorder";
    auto recorder = std::make_shared<bag::Recorder>(rec, ro);
    bus::NodeOptions lo;
    lo.context = ctx;
    lo.name = "listener";
    auto listener = std::make_shared<bus::Node>(lo);
    auto q = bus::QoS::reliable(1000);
    auto s1 = listener->create_subscription<RawScan>("/tiny/raw", q,
                                                     [&](const RawScan& m) { live["raw"].push_back(cdr(m)); });
    auto s2 = listener->create_subscription<LineScan>("/tiny/scan", q,
                                                      [&](const LineScan& m) { live["scan"].push_back(cdr(m)); });
    auto s3 = listener->create_subscription<LaserScan>(
        "/tiny/laser_scan", q, [&](const LaserScan& m) { live["laser_scan"].push_back(cdr(m)); });
    ex.add_node(recorder);
    ex.add_node(driver);
    ex.add_node(listener);
    ex.spin_until_idle();
    driver->pump(0ms);  // connect
    for (int s = 0; s < 40; ++s) {
      Bytes b = make_set(s);
      if (s == 17) b[3 * 1096 + 1095] = 0;  // one damaged set: dropped, a gap in set_index
      link->push(b);
      while (link->queued() > 0) driver->pump(0ms);
      ex.advance_to(ctx->clock().now() + 27ms);
    }
    ex.spin_until_idle();
    recorder->on_stop();
    driver->on_stop();
    io::unregister_memory_link("replay");
    EXPECT_EQ(recorder->stats().dropped, 0u);
  }
  ASSERT_EQ(live["scan"].size(), 39u);
  ASSERT_EQ(live["raw"].size(), 39u);
  ASSERT_EQ(live["laser_scan"].size(), 39u);

  // ---- the file holds exactly what was published.
  std::map<std::string, std::vector<Bytes>> in_bag;
  {
    bag::Reader reader;
    ASSERT_TRUE(reader.open(bag_path).ok());
    auto cursor = reader.read();
    bag::MessageView v;
    while (cursor->next(v)) in_bag[v.channel->topic].emplace_back(v.message.data.begin(), v.message.data.end());
    ASSERT_TRUE(cursor->status().ok()) << cursor->status().str();
  }
  EXPECT_EQ(in_bag["/tiny/raw"], live["raw"]);
  EXPECT_EQ(in_bag["/tiny/scan"], live["scan"]);
  EXPECT_EQ(in_bag["/tiny/laser_scan"], live["laser_scan"]);

  // ---- replayed: the bag's raw scans through the raw processor give the same scans.
  bag::ReplayOptions opts;
  opts.topics = {"/tiny/raw"};
  bag::Replay replay(bag_path, opts);
  replay.add<tl::RawProcessor>("processor",
                               {{"raw", "/tiny/raw"}, {"scan", "/again/scan"}, {"laser_scan", "/again/laser_scan"}},
                               {{"calibration", calib_path, {}}});
  const bag::ReplayResult out = replay.run();
  ASSERT_TRUE(out.status.ok()) << out.status.str();
  std::vector<Bytes> scans, laser_scans;
  for (const auto& m : out.messages<LineScan>("/again/scan")) scans.push_back(cdr(*m));
  for (const auto& m : out.messages<LaserScan>("/again/laser_scan")) laser_scans.push_back(cdr(*m));
  ASSERT_EQ(scans.size(), live["scan"].size());
  for (std::size_t i = 0; i < scans.size(); ++i) EXPECT_EQ(scans[i], live["scan"][i]) << "scan " << i;
  for (std::size_t i = 0; i < laser_scans.size(); ++i)
    EXPECT_EQ(laser_scans[i], live["laser_scan"][i]) << "laser scan " << i;
}

TEST(RawProcessor, RefusesRawScansThatCannotBeASet) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  auto sink = std::make_shared<bus::CaptureSink>();
  co.log_sink = sink;
  auto ctx = bus::Context::create(co);
  bus::DeterministicExecutor ex(ctx->clock());
  bus::NodeOptions o;
  o.context = ctx;
  o.name = "processor";
  o.param("calibration", std::string("public:K"));
  auto proc = std::make_shared<tl::RawProcessor>(o);
  bus::NodeOptions so;
  so.context = ctx;
  so.name = "source";
  auto src = std::make_shared<bus::Node>(so);
  auto pub = src->create_publisher<RawScan>("/raw");
  std::size_t scans = 0;
  auto sub = src->create_subscription<LineScan>("/scan", bus::QoS::keep_last(10), [&](const LineScan&) { ++scans; });
  ex.add_node(proc);
  ex.add_node(src);
  ex.spin_until_idle();
  auto bad = std::make_unique<RawScan>();
  bad->pixels = 100;
  pub->publish(std::move(bad));
  auto short_arrays = std::make_unique<RawScan>();
  short_arrays->pixels = 272;
  short_arrays->pulses = {20, 100};
  short_arrays->a.resize(272);
  short_arrays->b.resize(544);
  pub->publish(std::move(short_arrays));
  auto falling = std::make_unique<RawScan>();
  falling->pixels = 272;
  falling->pulses = {100, 20};
  falling->a.resize(544);
  falling->b.resize(544);
  falling->temperature_c = 45.0f;
  pub->publish(std::move(falling));
  ex.spin_until_idle();
  EXPECT_EQ(proc->refused(), 3u);
  EXPECT_EQ(scans, 0u);
  EXPECT_TRUE(sink->contains(bus::LogLevel::Error, "100 pixels"));
  EXPECT_TRUE(sink->contains(bus::LogLevel::Error, "do not hold"));
  EXPECT_TRUE(sink->contains(bus::LogLevel::Error, "must rise"));
}
