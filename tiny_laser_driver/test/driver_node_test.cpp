// SPDX-License-Identifier: Apache-2.0
// The driver node against an in-memory device, stepped on a sim clock with
// the deterministic executor (threaded: false): publishing, timestamps,
// reconnect with backoff, no partial scan, laser commands, diagnostics, and
// errors. One test runs the real I/O thread.
#include <gtest/gtest.h>

#include <stdlib.h>
#include <sys/stat.h>

#include <array>
#include <cmath>
#include <cstring>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/testing.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/nodes/register.hpp>

#include "synthetic_raw_set.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace tt = tinyline::tiny_laser_driver::testing;
namespace bus = tinyline::bus;
namespace io = tl::io;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;
using tinyline::diagnostic_msgs::msg::DiagnosticArray;
using tinyline::sensor_msgs::msg::LaserScan;
using tinyline::tinyline_msgs::msg::LaserCommand;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::RawScan;

namespace {

constexpr double kByteS = 10.0 / 2'000'000;

// A set whose effective pixels see k = b / (a + b) = 0.1 + 0.001 * p.
Bytes make_set(int seed = 0) {
  return tt::encode_synthetic_set(450, [seed](std::uint16_t pulses, std::size_t p) {
    const double k = 0.1 + 0.001 * static_cast<double>(p);
    const double sum = 0.3 * pulses + 0.2 * seed;  // 210 charge units at 700 pulses; seeds differ on the wire
    return std::pair{sum, k};
  });
}

using TempDir = tinyline::bus::testing::TempDir;

// A small fixture: the stepped sim-time graph of bus/testing.hpp from
// t = 100 s, an in-memory device reachable as mem:NAME, the driver, and
// everything it publishes kept (`io` also commands it).
struct Rig : bus::testing::NodeRig {
  TempDir tmp;
  std::string calib;
  std::shared_ptr<io::MemoryLink> link;
  std::string link_name;
  std::shared_ptr<tl::LaserDriver> driver;
  std::vector<std::shared_ptr<const RawScan>>& raws = collect<RawScan>("/raw", bus::QoS::keep_last(1000));
  std::vector<std::shared_ptr<const LineScan>> scans;
  std::vector<bus::Time> scan_seen_at;  // sim time when each LineScan arrived
  std::vector<std::shared_ptr<const LaserScan>>& laser_scans =
      collect<LaserScan>("/laser_scan", bus::QoS::keep_last(1000));
  std::vector<std::shared_ptr<const DiagnosticArray>>& diags =
      collect<DiagnosticArray>("/diagnostics", bus::QoS::keep_last(1000));
  std::shared_ptr<bus::Subscription<LineScan>> scan_sub;
  std::shared_ptr<bus::Publisher<LaserCommand>> commands;

  explicit Rig(std::vector<std::pair<std::string, bus::ParamValue>> extra = {}, bool start = true)
      : NodeRig({}, bus::Time::from_seconds(100.0)) {
    calib = (tmp.path / "linear.yaml").string();
    // distance_cm = 300 k: the expected distance of pixel p is 3 (0.1 + 0.001 p) m.
    tl::CalibrationModel::from_public_driver({0, 0, 0, 0, 0, 300, 0}, {}, 450, 0).save(calib);
    static int counter = 0;
    link_name = "rig" + std::to_string(++counter);
    link = io::MemoryLink::create(link_name);
    io::register_memory_link(link_name, link);
    bus::NodeOptions o;
    o.context = ctx;
    o.name = "laser";
    o.param("port", "mem:" + link_name).param("calibration", calib).param("threaded", false);
    for (auto& [k, v] : extra) o.param(k, v);
    driver = std::make_shared<tl::LaserDriver>(o);
    scan_sub = io->create_subscription<LineScan>("/scan", bus::QoS::keep_last(1000),
                                                 [this](const std::shared_ptr<const LineScan>& m) {
                                                   scans.push_back(m);
                                                   scan_seen_at.push_back(ctx->clock().now());
                                                 });
    commands = io->create_publisher<LaserCommand>("/laser_command");
    add(driver);
    if (start) ex.spin_until_idle();  // runs on_start
  }
  ~Rig() { io::unregister_memory_link(link_name); }

  bus::Time now() const { return ctx->clock().now(); }
  // Driver steps at the current sim time until the device's bytes are read, then deliver everything.
  void step() {
    for (int i = 0; i < 100; ++i) {
      driver->pump(0ms);
      if (link->queued() == 0) break;
    }
    ex.spin_until_idle();
  }
  // Moves sim time on by dt (firing timers), then steps.
  void advance(double dt_s) {
    ex.advance_to(now() + bus::from_seconds(dt_s));
    step();
  }
  std::string diag_value(const std::string& key) const {
    if (diags.empty() || diags.back()->status.empty()) return "";
    for (const auto& kv : diags.back()->status[0].values) {
      if (kv.key == key) return kv.value;
    }
    return "";
  }
};

}  // namespace

TEST(LaserDriverNode, PublishesRawLineAndLaserScans) {
  Rig rig;
  rig.step();  // connects
  ASSERT_TRUE(rig.driver->status().connected);
  Bytes stream;
  for (int s = 0; s < 3; ++s) {
    const Bytes set = make_set(s);
    stream.insert(stream.end(), set.begin(), set.end());
  }
  rig.link->push(stream);
  rig.step();
  ASSERT_EQ(rig.scans.size(), 3u);
  ASSERT_EQ(rig.raws.size(), 3u);
  ASSERT_EQ(rig.laser_scans.size(), 3u);

  const auto& raw = *rig.raws[0];
  EXPECT_EQ(raw.header.frame_id, "laser");
  EXPECT_EQ(raw.pixels, 272);
  EXPECT_EQ(raw.pulses, (std::vector<std::uint16_t>{20, 100, 200, 400, 700}));
  ASSERT_EQ(raw.a.size(), 5u * 272);
  EXPECT_FLOAT_EQ(raw.temperature_c, 45.0f);
  EXPECT_EQ(rig.raws[1]->set_index, 1u);

  const auto& scan = *rig.scans[2];
  ASSERT_EQ(scan.distance_m.size(), 272u);
  for (std::size_t p = 8; p < 264; ++p) {
    ASSERT_EQ(scan.status[p], LineScan::STATUS_VALID) << p;
    EXPECT_NEAR(scan.distance_m[p], 3.0 * (0.1 + 0.001 * p), 2e-3) << p;  // 0.1 charge-unit rounding of the wire
    EXPECT_EQ(scan.pulses[p], 700);
  }
  EXPECT_EQ(scan.status[0], LineScan::STATUS_DARK_PIXEL);
  EXPECT_TRUE(std::isnan(scan.distance_m[0]));
  EXPECT_EQ(scan.angles.size(), 272u);
  EXPECT_LT(scan.angles[8], 0.0f);
  EXPECT_GT(scan.angles[263], 0.0f);

  const auto& ls = *rig.laser_scans[2];
  EXPECT_EQ(ls.header.frame_id, "laser_scan");
  EXPECT_EQ(ls.ranges.size(), 256u);
  EXPECT_FLOAT_EQ(ls.angle_min, scan.angles[8]);
  EXPECT_NEAR(ls.ranges[0], scan.distance_m[8], 1e-6);
  EXPECT_NEAR(ls.ranges[255], scan.distance_m[263], 1e-6);
}

TEST(LaserDriverNode, PublishesTheLineAsPointCloud2OnlyWhenAsked) {
  Rig quiet;
  EXPECT_FALSE(quiet.ctx->graph().find("/cloud")) << "off by default";

  Rig rig({{"publish_cloud", true}});
  auto& clouds = rig.collect<tinyline::sensor_msgs::msg::PointCloud2>("/cloud", bus::QoS::keep_last(10));
  rig.step();
  rig.link->push(make_set());
  rig.step();
  ASSERT_EQ(clouds.size(), 1u);
  ASSERT_EQ(rig.scans.size(), 1u);
  const auto& c = *clouds[0];
  const auto& scan = *rig.scans[0];
  EXPECT_EQ(c.header.frame_id, "laser");
  EXPECT_EQ(c.header.stamp, scan.header.stamp);
  EXPECT_EQ(c.height, 1u);
  ASSERT_EQ(c.width, 272u);
  ASSERT_EQ(c.fields.size(), 4u);
  const char* names[] = {"x", "y", "z", "intensity"};
  for (std::size_t f = 0; f < 4; ++f) {
    EXPECT_EQ(c.fields[f].name, names[f]);
    EXPECT_EQ(c.fields[f].offset, 4 * f);
    EXPECT_EQ(c.fields[f].datatype, tinyline::sensor_msgs::msg::PointField::FLOAT32);
    EXPECT_EQ(c.fields[f].count, 1u);
  }
  EXPECT_EQ(c.point_step, 16u);
  EXPECT_EQ(c.row_step, 16u * 272);
  ASSERT_EQ(c.data.size(), 16u * 272);
  EXPECT_FALSE(c.is_dense);
  auto point = [&](std::size_t p) {
    std::array<float, 4> v{};
    std::memcpy(v.data(), c.data.data() + 16 * p, 16);
    return v;
  };
  EXPECT_TRUE(std::isnan(point(0)[0]));  // a dark pixel: no point
  for (std::size_t p = 8; p < 264; ++p) {
    const auto v = point(p);
    // distance_m along the pixel's ray in the x-z plane, z forward.
    EXPECT_NEAR(std::hypot(v[0], v[2]), scan.distance_m[p], 1e-5) << p;
    EXPECT_NEAR(std::atan2(v[0], v[2]), scan.angles[p], 1e-5) << p;
    EXPECT_EQ(v[1], 0.0f);
    EXPECT_EQ(v[3], scan.intensity[p]);
  }
}

TEST(LaserDriverNode, StampsAreTheLastByteTimeMinusTheTransmissionTime) {
  Rig rig;
  rig.step();
  Bytes stream = make_set(0);
  const Bytes second = make_set(1);
  stream.insert(stream.end(), second.begin(), second.end());
  stream.resize(stream.size() + 100, 0x00);  // 100 bytes after the second set, in the same read
  rig.link->push(stream);
  const bus::Time t = rig.now();
  rig.step();
  ASSERT_EQ(rig.scans.size(), 2u);
  // The read's last byte arrived at t; the second set's last byte 100 bytes earlier;
  // its last frame started 1096 bytes before that.
  const double expect2 = t.seconds() - (100 + 1096) * kByteS;
  const double expect1 = expect2 - 5 * 1096 * kByteS;
  EXPECT_NEAR(bus::Time::from_msg(rig.scans[1]->header.stamp).seconds(), expect2, 2e-9);
  EXPECT_NEAR(bus::Time::from_msg(rig.scans[0]->header.stamp).seconds(), expect1, 2e-9);
  EXPECT_EQ(rig.scans[0]->header.stamp, rig.raws[0]->header.stamp);

  // A third set read 10 ms later: scan_time is the spacing of the stamps.
  rig.ex.advance_to(t + 10ms);
  rig.link->push(make_set(2));
  rig.step();
  ASSERT_EQ(rig.laser_scans.size(), 3u);
  const double expect3 = t.seconds() + 0.010 - 1096 * kByteS;
  EXPECT_NEAR(bus::Time::from_msg(rig.scans[2]->header.stamp).seconds(), expect3, 2e-9);
  EXPECT_NEAR(rig.laser_scans[2]->scan_time, expect3 - expect2, 1e-6);
}

namespace {

Bytes distance_frame(std::uint16_t base, std::size_t stuck_pixel = 0, std::uint16_t stuck_value = 0) {
  tl::DistanceFrame f;
  for (std::size_t p = 8; p < 264; ++p) f.distance[p] = static_cast<std::uint16_t>(base + p);
  if (stuck_pixel) f.distance[stuck_pixel] = stuck_value;
  Bytes b;
  tl::encode_distance_frame(f, b);
  return b;
}

constexpr double kDistanceFrameS = 548 * kByteS;

}  // namespace

TEST(LaserDriverNode, DefaultsReadThePublishedFirmwaresDistanceFrames) {
  // Default parameters: distances in 0.1 mm, values above 32767 are ranges.
  Rig rig;
  rig.step();
  rig.link->push(distance_frame(35000));  // 3.5 m and beyond
  rig.step();
  rig.advance(0.05);  // nothing follows: the new content is published once its hold runs out
  ASSERT_EQ(rig.scans.size(), 1u);
  EXPECT_TRUE(rig.raws.empty());
  EXPECT_NEAR(rig.scans[0]->distance_m[100], 3.51, 1e-6);
  EXPECT_EQ(rig.scans[0]->status[100], LineScan::STATUS_VALID);
}

TEST(LaserDriverNode, RepeatedFramesAreOneMeasurementStampedAtTheirFirstArrival) {
  Rig rig;
  rig.step();
  const bus::Time t0 = rig.now();
  // The published firmware's DMA: each content many times back to back, a
  // new content every 100 ms, one frame torn at each change.
  std::vector<bus::Time> first_arrival;
  for (int cycle = 0; cycle < 3; ++cycle) {
    const Bytes content = distance_frame(static_cast<std::uint16_t>(5000 + 100 * cycle));
    if (cycle > 0) {
      Bytes torn = distance_frame(static_cast<std::uint16_t>(5000 + 100 * (cycle - 1)));
      std::copy(content.begin() + 301, content.end(), torn.begin() + 301);  // the buffer rewritten mid-frame
      rig.link->push(torn);
      rig.advance(kDistanceFrameS);
    }
    for (int r = 0; r < 30; ++r) {
      rig.link->push(content);
      rig.advance(kDistanceFrameS);
      if (r == 0) first_arrival.push_back(rig.now() - bus::from_seconds(kDistanceFrameS));
    }
  }
  rig.advance(0.05);
  ASSERT_EQ(rig.scans.size(), 3u);
  for (int cycle = 0; cycle < 3; ++cycle) {
    EXPECT_NEAR(rig.scans[static_cast<std::size_t>(cycle)]->distance_m[100], 0.01 * (50 + cycle) + 0.01, 1e-6);
    EXPECT_NEAR(bus::Time::from_msg(rig.scans[static_cast<std::size_t>(cycle)]->header.stamp).seconds(),
                first_arrival[static_cast<std::size_t>(cycle)].seconds(), 1e-6);
  }
  const auto st = rig.driver->status();
  EXPECT_EQ(st.distance_repeats.torn, 2u);
  EXPECT_EQ(st.distance_repeats.repeats, 3u * 29u);
  EXPECT_EQ(st.distance_repeats.fresh, 3u);
  (void)t0;
  rig.advance(1.0);  // diagnostics
  EXPECT_EQ(rig.diag_value("frame_kinds"), "distance");
  EXPECT_EQ(rig.diag_value("torn_frames"), "2");
}

TEST(LaserDriverNode, APixelThatNeverChangesWhileItsNeighboursDoIsFlaggedStale) {
  Rig rig({{"stale_after", std::int64_t{5}}});
  rig.step();
  for (int k = 0; k < 12; ++k) {
    rig.link->push(distance_frame(static_cast<std::uint16_t>(4000 + 7 * k), 120, 4321));
    rig.advance(0.05);
  }
  ASSERT_EQ(rig.scans.size(), 12u);
  EXPECT_EQ(rig.scans[3]->status[120], LineScan::STATUS_VALID);  // not yet: 4 unchanged measurements
  EXPECT_EQ(rig.scans.back()->status[120], LineScan::STATUS_STALE);
  EXPECT_TRUE(std::isnan(rig.scans.back()->distance_m[120]));
  EXPECT_EQ(rig.scans.back()->status[119], LineScan::STATUS_VALID);
  EXPECT_EQ(rig.scans.back()->status[121], LineScan::STATUS_VALID);
  rig.advance(1.0);
  EXPECT_EQ(rig.diag_value("stale_pixels"), "1");
}

TEST(LaserDriverNode, AnImplausibleUnitAndAnUnexpectedKindAreReportedNotDropped) {
  // The old simulator's millimetres read with the default 0.1 mm: everything
  // under 5 cm. And `mode: raw` expected while distances come.
  Rig rig({{"mode", std::string("raw")}});
  rig.step();
  for (int k = 0; k < 5; ++k) {
    rig.link->push(distance_frame(static_cast<std::uint16_t>(300 + k)));  // 300-563 units: 3-6 cm... as mm, 0.3-0.56 m
    rig.advance(0.05);
  }
  ASSERT_EQ(rig.scans.size(), 5u);  // published all the same
  rig.advance(1.0);
  ASSERT_FALSE(rig.diags.empty());
  const auto& st = rig.diags.back()->status[0];
  EXPECT_EQ(st.level, tinyline::diagnostic_msgs::msg::DiagnosticStatus::WARN);
  EXPECT_NE(st.message.find("expected raw frames, the sensor sends distance frames"), std::string::npos) << st.message;
  EXPECT_NE(rig.diag_value("distance_unit_check").find("under 0.05 m"), std::string::npos)
      << rig.diag_value("distance_unit_check");
}

TEST(LaserDriverNode, ASensorThatIgnoresLaserOffIsReported) {
  // Sequence mode: the driver tells the laser off at connect; a sensor with
  // the published firmware goes on measuring.
  Rig rig({{"sequence_slot", std::int64_t{0}}});
  rig.step();
  ASSERT_EQ(rig.link->take_written(), tl::cmd_laser(false));
  for (int k = 0; k < 5; ++k) {
    rig.advance(0.1);
    rig.link->push(distance_frame(static_cast<std::uint16_t>(5000 + k)));
    rig.step();
  }
  rig.advance(1.0);
  EXPECT_EQ(rig.diag_value("laser_off_obeyed"), "no");
  EXPECT_NE(rig.diag_value("commands").find("laser off: sent 1, obeyed 0, ignored 1"), std::string::npos)
      << rig.diag_value("commands");
  EXPECT_NE(rig.diags.back()->status[0].message.find("ignores laser off"), std::string::npos);
}

TEST(LaserDriverNode, DistanceUnitStaysAParameter) {
  Rig rig({{"mode", std::string("distance")}, {"distance_unit_m", 0.001}});
  rig.step();
  rig.link->push(distance_frame(500));
  rig.link->push(distance_frame(600));
  rig.step();
  rig.advance(0.05);
  ASSERT_EQ(rig.scans.size(), 2u);
  EXPECT_NEAR(rig.scans[0]->distance_m[100], 0.6, 1e-6);
  EXPECT_EQ(rig.scans[1]->set_index, 1u);
}

TEST(LaserDriverNode, ReconnectsAfterAnUnplugWithinASecondAndNeverPublishesAPartialSet) {
  Rig rig;
  rig.step();
  const Bytes set = make_set(0);
  // Device streams; the host steps every 10 ms of sim time.
  rig.link->push(set);
  rig.step();
  ASSERT_EQ(rig.scans.size(), 1u);
  // Half a set, then the cable is pulled.
  rig.link->push({set.data(), set.size() / 2});
  rig.step();
  rig.link->unplug();
  rig.step();
  auto st = rig.driver->status();
  EXPECT_FALSE(st.connected);
  EXPECT_EQ(st.disconnects, 1u);
  EXPECT_EQ(st.last_error, io::IoError::kDisconnected);
  EXPECT_EQ(st.parser.dropped(tl::DropReason::kIncompleteSet), 1u);  // the half set: counted, not published
  EXPECT_EQ(rig.scans.size(), 1u);

  // Three seconds without the device: the driver keeps retrying, backing off.
  for (int i = 0; i < 300; ++i) rig.advance(0.01);
  st = rig.driver->status();
  EXPECT_EQ(st.last_error, io::IoError::kNotFound);
  EXPECT_GE(st.open_failures, 5u);
  EXPECT_LE(st.open_failures, 12u);  // 50, 100, 200, 400 ms, then every 500 ms: not a busy loop
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Warn, "lost the sensor"));

  // Replug. The device streams a set every 30 ms from then on (while someone listens).
  rig.link->replug();
  const bus::Time replugged = rig.now();
  for (int i = 0; i < 150 && rig.scans.size() < 2; ++i) {
    if (i % 3 == 0) rig.link->push(set);
    rig.advance(0.01);
  }
  ASSERT_EQ(rig.scans.size(), 2u);
  const double resumed_after_s = (rig.scan_seen_at.back() - replugged).count() * 1e-9;
  EXPECT_LE(resumed_after_s, 1.0);
  EXPECT_TRUE(rig.driver->status().connected);
  EXPECT_EQ(rig.driver->status().connects, 2u);
  // Every scan published is whole.
  for (const auto& s : rig.scans) EXPECT_EQ(s->distance_m.size(), 272u);
  for (const auto& r : rig.raws) EXPECT_EQ(r->a.size(), 5u * 272);
}

TEST(LaserDriverNode, SequenceModeFollowsTheSlotAndNameOrders) {
  Rig rig({{"sequence_slot", std::int64_t{2}}, {"sensor_name", std::string("left")}});
  rig.step();
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(false));  // off until its slot comes
  auto order = [&](std::vector<std::uint16_t> slots, std::vector<std::string> names = {}, std::vector<bool> on = {}) {
    auto m = std::make_unique<LaserCommand>();
    m->active_slots = std::move(slots);
    m->sensors = std::move(names);
    m->laser_on = std::move(on);
    rig.commands->publish(std::move(m));
    rig.ex.spin_until_idle();
    rig.step();
  };
  order({2});
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(true));
  order({2, 5});
  EXPECT_TRUE(rig.link->take_written().empty());  // no change, nothing sent
  order({1});
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(false));
  order({1}, {"left"}, {true});  // by name beats the slot rule
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(true));
  order({}, {"right"}, {false});  // someone else's order; the slot rule says off
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(false));
  order({2}, {"left"}, {});  // malformed: names without states, by-name part ignored
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(true));
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Warn, "by-name orders are ignored"));
  EXPECT_EQ(rig.driver->status().laser_on, true);

  // After a replug the sensor has forgotten: the driver tells it again.
  rig.link->unplug();
  rig.step();
  rig.link->replug();
  rig.advance(0.2);
  EXPECT_EQ(rig.link->take_written(), tl::cmd_laser(true));
}

TEST(LaserDriverNode, NotInSequenceModeItSendsNothing) {
  Rig rig;
  rig.step();
  auto m = std::make_unique<LaserCommand>();
  m->active_slots = {0, 1, 2};
  rig.commands->publish(std::move(m));
  rig.ex.spin_until_idle();
  rig.step();
  EXPECT_TRUE(rig.link->take_written().empty());
}

TEST(LaserDriverNode, DiagnosticsReportRateDropsAndTheLinkState) {
  Rig rig;
  rig.step();
  rig.ex.advance_to(rig.now() + 1s);  // a first report to count from
  Bytes bad = make_set(1);
  bad[1094] = 0;  // a wrong ender: its set is lost
  for (int i = 0; i < 10; ++i) {
    rig.link->push(i == 4 ? bad : make_set(i));  // each set its own content: an equal one is a repeat
    rig.step();
    rig.ex.advance_to(rig.now() + 100ms);  // the last one reaches the next report
  }
  ASSERT_GE(rig.diags.size(), 2u);
  const auto& st = rig.diags.back()->status.at(0);
  EXPECT_EQ(st.level, tinyline::diagnostic_msgs::msg::DiagnosticStatus::WARN);
  EXPECT_EQ(st.name, "/laser: tiny laser link");
  EXPECT_EQ(st.hardware_id, "mem:" + rig.link_name);
  EXPECT_EQ(rig.diag_value("drops_bad_ender"), "1");
  EXPECT_EQ(rig.diag_value("drops_incomplete_set"), "1");
  EXPECT_EQ(rig.diag_value("frame_rate_hz"), "9.00");
  EXPECT_EQ(rig.diag_value("state"), "connected");
  EXPECT_EQ(rig.diag_value("temperature_c"), "45.0");
  EXPECT_EQ(rig.diag_value("saturated_share"), "0.0000");
  // 10 sets of 5,480 bytes in a second at 2 Mbaud.
  EXPECT_NEAR(std::stod(rig.diag_value("link_utilisation")), 10 * 5480 * 10 / 2e6, 1e-3);

  rig.link->unplug();
  rig.step();
  rig.ex.advance_to(rig.now() + 1s);
  const auto& down = rig.diags.back()->status.at(0);
  EXPECT_EQ(down.level, tinyline::diagnostic_msgs::msg::DiagnosticStatus::ERROR);
  EXPECT_NE(down.message.find("no device"), std::string::npos) << down.message;
  EXPECT_EQ(rig.diag_value("state"), "disconnected");
}

TEST(LaserDriverNode, ASilentPortIsNeverStreamingAndItsSilenceCountsFromTheConnect) {
  using tinyline::diagnostic_msgs::msg::DiagnosticStatus;
  Rig rig;  // the sim clock starts at 100 s: an unset time would read as 100 s of silence
  rig.step();
  ASSERT_TRUE(rig.driver->status().connected);
  const bus::Time connected = rig.now();
  rig.advance(0.5);
  rig.ex.advance_to(connected + 1s);  // the first report, no byte yet
  ASSERT_FALSE(rig.diags.empty());
  const auto first = rig.diags.back()->status.at(0);
  EXPECT_EQ(first.message.find("streaming"), std::string::npos) << first.message;
  EXPECT_EQ(rig.diag_value("bytes_per_s"), "0");
  rig.ex.advance_to(connected + 5s);
  const auto later = rig.diags.back()->status.at(0);
  EXPECT_EQ(later.level, DiagnosticStatus::WARN);
  EXPECT_EQ(later.message, "connected, but no data for 5.0 s");

  // Data, then silence: counted from the last byte.
  rig.link->push(make_set(1));
  rig.step();
  rig.ex.advance_to(connected + 6s);
  EXPECT_EQ(rig.diags.back()->status.at(0).message, "streaming");
  rig.ex.advance_to(connected + 8s);
  EXPECT_EQ(rig.diags.back()->status.at(0).message, "connected, but no data for 3.0 s");

  // Unplugged and back: the old connection's last byte does not count.
  rig.link->unplug();
  rig.step();
  rig.link->replug();
  rig.advance(0.3);
  ASSERT_TRUE(rig.driver->status().connected);
  const bus::Time again = rig.driver->status().connected_at;
  rig.ex.advance_to(again + 4s);
  const auto back = rig.diags.back()->status.at(0);
  EXPECT_EQ(back.level, DiagnosticStatus::WARN);
  EXPECT_NE(back.message.find("connected, but no data for 3."), std::string::npos) << back.message;
}

TEST(LaserDriverNode, ABadCalibrationFileStopsTheNodeBeforeItStartsNamingFileLineAndField) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  auto ctx = bus::Context::create(co);
  auto make = [&](const std::string& calibration) {
    bus::NodeOptions o;
    o.context = ctx;
    o.name = "laser";
    o.param("port", std::string("/dev/ttyUSB9")).param("calibration", calibration).param("threaded", false);
    return std::make_shared<tl::LaserDriver>(o);
  };
  TempDir tmp;
  // A FIFO would block the read for ever, a device would never end: refused when the node is built.
  const std::string fifo = (tmp.path / "fifo.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {fifo, std::string("/dev/zero")}) {
    try {
      make(path);
      ADD_FAILURE() << "built with " << path;
    } catch (const bus::ParamError& e) {
      EXPECT_NE(std::string(e.what()).find("parameter 'calibration'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    }
  }
  // Bad content: on_configure (before any node starts, and in launch --check) names file, line and field.
  const std::string bad = (tmp.path / "bad.yaml").string();
  {
    std::ofstream out(bad);
    out << tl::CalibrationModel::from_public_driver({0, 0, 0, 0, 0, 300, 0}, {}, 450, 0).to_yaml()
        << "temperature: {reference_c: 20, coefficient_m_per_c: 0}\n";
  }
  auto node = make(bad);
  try {
    node->on_configure();
    ADD_FAILURE() << "configured with a repeated section";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad + ":"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("field 'temperature': given twice"), std::string::npos) << e.what();
  }
}

TEST(LaserDriverNode, BadSettingsSayWhatIsWrong) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  auto ctx = bus::Context::create(co);
  auto make = [&](std::vector<std::pair<std::string, bus::ParamValue>> params) {
    bus::NodeOptions o;
    o.context = ctx;
    o.name = "laser";
    for (auto& [k, v] : params) o.param(k, v);
    return std::make_shared<tl::LaserDriver>(o);
  };
  try {
    make({{"port", std::string("bogus:x")}});
    FAIL() << "accepted an unknown port scheme";
  } catch (const bus::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter 'port'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make({{"mode", std::string("fast")}}), bus::ParamError);
  EXPECT_THROW(make({{"focal_mm", 0.0}}), bus::ParamError);
  EXPECT_THROW(make({{"reconnect_min_s", 2.0}, {"reconnect_max_s", 1.0}}), bus::ParamError);

  try {
    make({{"calibration", std::string("/no/such/calibration.yaml")}, {"threaded", false}});
    FAIL() << "built without its calibration";
  } catch (const bus::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/calibration.yaml"), std::string::npos) << e.what();
  }
  auto unknown = make({{"calibration", std::string("public:Q")}, {"threaded", false}});
  EXPECT_THROW(unknown->on_start(), std::runtime_error);
  auto known = make({{"calibration", std::string("public:K")}, {"threaded", false}});
  EXPECT_NO_THROW(known->on_start());
  auto shipped = make({{"calibration", std::string("default")}, {"threaded", false}});
  EXPECT_NO_THROW(shipped->on_start());
}

TEST(LaserDriverNode, IsRegisteredForLaunchFiles) {
  bus::NodeRegistry r;
  tl::register_nodes(r);
  ASSERT_NE(r.find("tiny_laser_driver", "laser_driver"), nullptr);
}

TEST(LaserDriverNode, TheIoThreadPublishesWhatTheDeviceSends) {
  // Wall clock, a real executor thread and the driver's own I/O thread.
  TempDir tmp;
  const std::string calib = (tmp.path / "linear.yaml").string();
  tl::CalibrationModel::from_public_driver({0, 0, 0, 0, 0, 300, 0}, {}, 450, 0).save(calib);
  auto ctx = bus::Context::create({bus::ClockType::Wall, std::make_shared<bus::CaptureSink>()});
  auto link = io::MemoryLink::create("threaded");
  io::register_memory_link("threaded", link);
  bus::NodeOptions o;
  o.context = ctx;
  o.name = "laser";
  o.param("port", std::string("mem:threaded")).param("calibration", calib);
  auto driver = std::make_shared<tl::LaserDriver>(o);
  bus::NodeOptions lo;
  lo.context = ctx;
  lo.name = "listener";
  auto listener = std::make_shared<bus::Node>(lo);
  std::mutex mu;
  std::condition_variable cv;
  std::size_t got = 0;
  auto sub = listener->create_subscription<LineScan>("/scan", bus::QoS::keep_last(100), [&](const LineScan&) {
    std::lock_guard lk(mu);
    ++got;
    cv.notify_all();
  });
  bus::SingleThreadedExecutor ex(ctx->clock());
  ex.add_node(driver);
  ex.add_node(listener);
  std::thread spinner([&] { ex.spin(); });
  // Wait (on a condition, not a sleep) until the I/O thread has the port open.
  ASSERT_TRUE(link->wait_for_host(10s));
  for (int i = 0; i < 5; ++i) link->push(make_set(i));
  {
    std::unique_lock lk(mu);
    cv.wait_for(lk, 10s, [&] { return got >= 5; });
  }
  EXPECT_EQ(got, 5u);
  ex.stop();
  spinner.join();
  driver->on_stop();
  io::unregister_memory_link("threaded");
}
