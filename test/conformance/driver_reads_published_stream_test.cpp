// SPDX-License-Identifier: Apache-2.0
// The driver node, with default parameters, reads a byte stream that
// published_stream.py lays out exactly as the published firmware sends it
// (written from the firmware's sources, not from tinyline's encoder): the
// same frame back to back, a torn frame at each buffer update, values above
// 32767, a stuck pixel, the reader joining mid-frame. It must publish each
// buffer content once, stamped at its first whole frame, with the right
// ranges, drop the torn frames, and flag the stuck pixel.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include <tinyline/bus/testing.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace bus = tinyline::bus;
namespace io = tl::io;
using tinyline::tinyline_msgs::msg::LineScan;

namespace {

struct Generated {
  std::vector<std::uint8_t> bytes;
  YAML::Node expected;  // JSON is YAML
};

Generated generate(const std::string& dir, int cycles) {
  const std::string cmd = std::string(TINYLINE_VENV_PYTHON) + " " + TINYLINE_SOURCE_DIR +
                          "/test/conformance/published_stream.py " + dir + " " + std::to_string(cycles);
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  Generated g;
  std::ifstream in(dir + "/stream.bin", std::ios::binary);
  g.bytes.assign(std::istreambuf_iterator<char>(in), {});
  g.expected = YAML::LoadFile(dir + "/expected.json");
  return g;
}

}  // namespace

TEST(Conformance, TheDriverReadsThePublishedFirmwaresStreamWithDefaultParameters) {
  bus::testing::TempDir tmp;
  const int cycles = 26;  // more fresh measurements than stale_after (20)
  const Generated g = generate(tmp.path.string(), cycles);
  ASSERT_GT(g.bytes.size(), 100000u);

  bus::testing::NodeRig rig({}, bus::Time::from_seconds(100.0));
  auto link = io::MemoryLink::create("published");
  io::register_memory_link("published", link);
  auto& scans = rig.collect<LineScan>("/scan", bus::QoS::keep_last(1000));
  bus::NodeOptions o;
  o.context = rig.ctx;
  o.name = "laser";
  o.param("port", std::string("mem:published")).param("threaded", false);  // nothing else: the defaults
  auto driver = std::make_shared<tl::LaserDriver>(o);
  rig.add(driver);
  rig.ex.spin_until_idle();
  driver->pump(std::chrono::milliseconds(0));  // connects

  // The bytes arrive at the link rate, 548 at a time.
  const double byte_s = 10.0 / 2'000'000;
  const bus::Time t0 = rig.ctx->clock().now();
  for (std::size_t at = 0; at < g.bytes.size(); at += 548) {
    const std::size_t n = std::min<std::size_t>(548, g.bytes.size() - at);
    link->push({g.bytes.data() + at, n});
    rig.ex.advance_to(t0 + bus::from_seconds(static_cast<double>(at + n) * byte_s));
    driver->pump(std::chrono::milliseconds(0));
    rig.ex.spin_until_idle();
  }
  rig.ex.advance_to(rig.ctx->clock().now() + bus::from_seconds(0.1));
  driver->pump(std::chrono::milliseconds(0));
  rig.ex.spin_until_idle();

  const auto& cyc = g.expected["cycles"];
  ASSERT_EQ(scans.size(), static_cast<std::size_t>(cycles)) << "one scan per buffer content, none for repeats or tears";
  const int stuck = g.expected["stuck_pixel"].as<int>();
  for (int c = 0; c < cycles; ++c) {
    const LineScan& s = *scans[static_cast<std::size_t>(c)];
    const auto words = cyc[c]["words"].as<std::vector<int>>();
    int beyond_32767 = 0;
    for (std::size_t p = 8; p < 264; ++p) {
      if (static_cast<int>(p) == stuck) continue;
      ASSERT_EQ(s.status[p], LineScan::STATUS_VALID) << "cycle " << c << " pixel " << p;
      ASSERT_NEAR(s.distance_m[p], words[p] * 1e-4, 1e-6) << "cycle " << c << " pixel " << p;
      beyond_32767 += words[p] > 32767 ? 1 : 0;
    }
    EXPECT_EQ(beyond_32767, 50) << "the far wall, 4.2 m and more";
    // Stamped at the start of its first whole frame.
    const double first_end = cyc[c]["first_frame_end"].as<double>();
    EXPECT_NEAR(bus::Time::from_msg(s.header.stamp).seconds(),
                (t0 + bus::from_seconds((first_end - 548) * byte_s)).seconds(), 1e-6)
        << "cycle " << c;
  }
  EXPECT_EQ(scans[5]->status[static_cast<std::size_t>(stuck)], LineScan::STATUS_VALID);
  EXPECT_EQ(scans.back()->status[static_cast<std::size_t>(stuck)], LineScan::STATUS_STALE);
  const auto st = driver->status();
  EXPECT_EQ(st.distance_repeats.fresh, static_cast<std::uint64_t>(cycles));
  EXPECT_GE(st.distance_repeats.torn, static_cast<std::uint64_t>(cycles - 2));
  EXPECT_GT(st.distance_repeats.repeats, static_cast<std::uint64_t>(30 * cycles));
  EXPECT_EQ(st.parser.frames_dropped(), 0u);
  io::unregister_memory_link("published");
}
