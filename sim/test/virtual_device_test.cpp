// SPDX-License-Identifier: Apache-2.0
// The virtual device through its pseudo-terminal, as a host sees it. These
// tests wait for bytes with poll() deadlines (the device runs on the wall
// clock, like the hardware); none takes more than a couple of seconds.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <system_error>

#include <tiny_laser_driver/protocol.hpp>

#include <sim/virtual_device.hpp>

using namespace tinyline::sim;
namespace tld = tinyline::tiny_laser_driver;
using Clock = std::chrono::steady_clock;

namespace {

std::string scene_path() { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml"; }

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() / ("tinyline_vdev_" + std::to_string(::getpid()) + "_" +
                                                     std::to_string(Clock::now().time_since_epoch().count()));
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

// A host: opens the port raw at 2 Mbaud and reads with a deadline.
class Host {
 public:
  explicit Host(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (fd_ >= 0) {
      termios t{};
      tcgetattr(fd_, &t);
      cfmakeraw(&t);
      cfsetispeed(&t, B2000000);
      cfsetospeed(&t, B2000000);
      tcsetattr(fd_, TCSANOW, &t);
    }
  }
  ~Host() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool ok() const { return fd_ >= 0; }
  void send(const std::vector<std::uint8_t>& b) {
    ASSERT_EQ(::write(fd_, b.data(), b.size()), static_cast<ssize_t>(b.size()));
  }
  /// Reads into the parser until `done()` or the deadline; returns false on EOF/error (device gone).
  template <class Done>
  bool read_until(tld::Parser& parser, double seconds, Done done, std::size_t* bytes = nullptr) {
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    std::uint8_t buf[4096];
    while (!done() && Clock::now() < end) {
      pollfd p{fd_, POLLIN, 0};
      const int ms = static_cast<int>(
          std::max<long>(1, std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count()));
      if (::poll(&p, 1, ms) <= 0) continue;
      const ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n <= 0) {
        if (n < 0 && errno == EAGAIN) continue;
        return false;
      }
      if (bytes) *bytes += static_cast<std::size_t>(n);
      parser.feed(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n)));
    }
    return true;
  }

 private:
  int fd_ = -1;
};

std::vector<tld::RawSet> take_sets(tld::Parser& p) {
  std::vector<tld::RawSet> out;
  while (auto s = p.next_set()) out.push_back(std::move(*s));
  return out;
}

}  // namespace

TEST(VirtualDevice, StreamsRawSetsThatMatchTheSimulation) {
  TempDir dir;
  auto sys = SimulatedSystem::from_file(scene_path());
  VirtualDeviceOptions o;
  o.link_path = (dir.path / "ttyTINY0").string();
  VirtualDevice dev(sys, o);
  std::mutex mu;
  std::vector<SensorSet> truth;
  dev.on_set([&](const SensorSet& s) {
    std::lock_guard lock(mu);
    truth.push_back(s);
  });
  dev.start();
  ASSERT_TRUE(std::filesystem::is_symlink(o.link_path));
  Host host(dev.path());
  ASSERT_TRUE(host.ok());
  tld::Parser parser;
  std::vector<tld::RawSet> sets;
  ASSERT_TRUE(host.read_until(parser, 3.0, [&] {
    auto more = take_sets(parser);
    sets.insert(sets.end(), more.begin(), more.end());
    return sets.size() >= 4;
  }));
  ASSERT_GE(sets.size(), 4u);
  EXPECT_EQ(parser.stats().dropped(tld::DropReason::kBadEnder), 0u);
  const auto& params = sys->sensor(0).params();
  for (const auto& s : sets) {
    ASSERT_EQ(s.frames.size(), params.acquisition.raw_pulses.size());
    for (std::size_t k = 0; k < s.frames.size(); ++k) EXPECT_EQ(s.frames[k].pulses, params.acquisition.raw_pulses[k]);
    EXPECT_NEAR(s.frames.back().temperature_decic / 10.0, params.thermal.warm_c, 1.0);
  }
  // The bytes are the simulated charges x 10: find the set on the wire among the simulated ones.
  std::lock_guard lock(mu);
  const auto& wire = sets.back().frames[2];
  bool found = false;
  for (const auto& t : truth) {
    if (std::lround(t.readouts[2].a[136] * 10.0) == wire.a[136] &&
        std::lround(t.readouts[2].b[140] * 10.0) == wire.b[140])
      found = true;
  }
  EXPECT_TRUE(found);
}

TEST(VirtualDevice, PacesFramesAtTheLinkRate) {
  auto sys = SimulatedSystem::from_file(scene_path());
  VirtualDeviceOptions o;
  o.baud = 200000.0;  // 20 kB/s: a raw set (5,480 bytes) takes 274 ms
  VirtualDevice dev(sys, o);
  dev.start();
  Host host(dev.path());
  ASSERT_TRUE(host.ok());
  tld::Parser parser;
  std::size_t bytes = 0;
  const auto t0 = Clock::now();
  host.read_until(
      parser, 0.6, [] { return false; }, &bytes);
  const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_LE(static_cast<double>(bytes), 20000.0 * dt + 1100.0);  // never faster than the link
  EXPECT_GE(static_cast<double>(bytes), 0.5 * 20000.0 * dt);     // and keeps it busy
  EXPECT_GT(dev.stats().frames_overflowed, 0u);                  // the firmware makes sets faster than 20 kB/s carries
}

TEST(VirtualDevice, SurvivesTheHostClosingAndReopening) {
  TempDir dir;
  VirtualDeviceOptions o;
  o.link_path = (dir.path / "ttyTINY0").string();
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  dev.start();
  for (int round = 0; round < 3; ++round) {
    Host host(o.link_path);
    ASSERT_TRUE(host.ok()) << round;
    tld::Parser parser;
    std::size_t n = 0;
    ASSERT_TRUE(host.read_until(parser, 2.0, [&] {
      n += take_sets(parser).size();
      return n >= 2;
    }));
    EXPECT_GE(n, 2u) << round;
    host.close();
  }
  EXPECT_GE(dev.stats().host_opens, 1u);  // a quick close/open may go unnoticed; the data must not
}

// Regression: --link replaced whatever was at its path (a user's file, the
// scene, a device, a link) through PATH.tmp and removed it on stop.
TEST(VirtualDevice, ALinkPathThatIsTakenIsRefusedAndOnlyItsOwnLinkIsRemoved) {
  TempDir dir;
  const std::string link = (dir.path / "ttyTINY0").string();
  const auto text = [](const std::string& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  std::ofstream(link) << "a user's file";
  std::ofstream(link + ".tmp") << "another";
  VirtualDeviceOptions o;
  o.link_path = link;
  {
    VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
    try {
      dev.start();
      ADD_FAILURE() << "started over a user's file";
    } catch (const std::system_error& e) {
      EXPECT_NE(std::string(e.what()).find("'" + link + "' exists and is not this device's link"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(text(link), "a user's file");
  EXPECT_EQ(text(link + ".tmp"), "another");
  std::filesystem::remove(link);
  {
    VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
    dev.start();
    ASSERT_TRUE(std::filesystem::is_symlink(link));
    std::filesystem::remove(link);  // someone puts their own file there while it serves
    std::ofstream(link) << "theirs";
    dev.stop();
  }
  EXPECT_EQ(text(link), "theirs");
}

TEST(VirtualDevice, UnplugRemovesThePathAndReplugBringsItBack) {
  TempDir dir;
  VirtualDeviceOptions o;
  o.link_path = (dir.path / "ttyTINY0").string();
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  dev.start();
  Host host(o.link_path);
  ASSERT_TRUE(host.ok());
  tld::Parser parser;
  std::size_t n = 0;
  ASSERT_TRUE(host.read_until(parser, 2.0, [&] { return (n += take_sets(parser).size()) >= 1; }));
  dev.unplug();
  EXPECT_FALSE(std::filesystem::exists(o.link_path));
  EXPECT_FALSE(dev.plugged());
  // The open port reports the loss (EOF or EIO) instead of hanging.
  EXPECT_FALSE(host.read_until(parser, 1.0, [] { return false; }));
  host.close();
  EXPECT_FALSE(Host(o.link_path).ok());
  dev.replug();
  ASSERT_TRUE(std::filesystem::is_symlink(o.link_path));
  Host again(o.link_path);
  ASSERT_TRUE(again.ok());
  tld::Parser p2;
  n = 0;
  ASSERT_TRUE(again.read_until(p2, 2.0, [&] { return (n += take_sets(p2).size()) >= 2; }));
  EXPECT_GE(n, 2u);
  EXPECT_EQ(dev.stats().replugs, 1u);
}

TEST(VirtualDevice, ByteErrorsAndDropsOnlyCostFrames) {
  VirtualDeviceOptions o;
  o.faults.byte_error_rate = 2e-4;
  o.faults.byte_drop_rate = 1e-4;
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  dev.start();
  Host host(dev.path());
  tld::Parser parser;
  std::size_t good = 0;
  host.read_until(parser, 1.5, [&] { return (good += take_sets(parser).size()) >= 15; });
  const auto st = dev.stats();
  EXPECT_GT(st.bytes_corrupted + st.bytes_dropped, 0u);
  EXPECT_GT(good, 5u);
  // Damage shows as dropped frames or sets, never as a crash or an endless hunt.
  const auto& ps = parser.stats();
  EXPECT_GT(ps.dropped(tld::DropReason::kBadEnder) + ps.dropped(tld::DropReason::kIncompleteSet) +
                ps.dropped(tld::DropReason::kGarbage) + ps.dropped(tld::DropReason::kBadField),
            0u);
}

TEST(VirtualDevice, SingleShotCommandsOfTheCalibrationFirmware) {
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()));
  dev.start();
  Host host(dev.path());
  ASSERT_TRUE(host.ok());
  host.send(tld::cmd_reset(25));  // 'R', 25: single shot with 250 pulses
  tld::Parser drain;
  host.read_until(drain, 0.2, [] { return false; });  // frames in flight before the command
  ASSERT_EQ(dev.mode(), FirmwareMode::kSingleShot);
  tld::Parser parser({1});
  host.send(tld::cmd_sample());
  std::vector<tld::RawSet> sets;
  host.read_until(parser, 1.0, [&] {
    auto m = take_sets(parser);
    sets.insert(sets.end(), m.begin(), m.end());
    return !sets.empty();
  });
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_EQ(sets[0].frames[0].pulses, 250);
  EXPECT_TRUE(sets[0].frames[0].last);
  // Nothing more until the next sample command.
  host.read_until(parser, 0.2, [] { return false; });
  EXPECT_FALSE(parser.next_set());
  host.send(tld::cmd_framed(tld::FramedCommand::kSample, std::vector<std::uint8_t>{0, 0}));
  host.read_until(parser, 1.0, [&] { return static_cast<bool>(parser.next_set()); });
  EXPECT_EQ(parser.stats().sets, 2u);
}

TEST(VirtualDevice, DistanceModeReportsTenthsOfAMillimetre) {
  VirtualDeviceOptions o;
  o.mode = FirmwareMode::kDistance;
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  dev.start();
  Host host(dev.path());
  tld::Parser parser;
  std::optional<tld::DistanceFrame> f;
  host.read_until(parser, 2.0, [&] { return (f = parser.next_distance()).has_value(); });
  ASSERT_TRUE(f);
  EXPECT_EQ(f->distance[0], 0);  // dark pixels carry no range
  EXPECT_EQ(f->distance[271], 0);
  // The target is 0.5 m away; pixel 136 looks along the axis.
  EXPECT_NEAR(f->distance[136], 5000, 500);  // one polynomial for all pixels: a few cm per pixel
  int valid = 0;
  for (int i = 8; i < 264; ++i) valid += f->distance[static_cast<std::size_t>(i)] > 0 ? 1 : 0;
  EXPECT_GT(valid, 200);
  // Switching to raw mode by command.
  host.send(tld::cmd_stream_mode(tld::StreamMode::Raw));
  tld::Parser raw;
  std::size_t n = 0;
  host.read_until(raw, 2.0, [&] { return (n += take_sets(raw).size()) >= 1; });
  EXPECT_GE(n, 1u);
  EXPECT_EQ(dev.mode(), FirmwareMode::kRaw);
}

TEST(VirtualDevice, CountsTheHostsGarbage) {
  // Bytes that start no command are counted as they arrive (they once were
  // read before the parser had seen them, and never counted).
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()));
  dev.start();
  Host host(dev.path());
  ASSERT_TRUE(host.ok());
  host.send({'x', 'y', 'z', 0x00});
  host.send(tld::cmd_laser(true));  // and a command after them, understood
  const auto end = Clock::now() + std::chrono::seconds(3);
  while (Clock::now() < end && (dev.stats().command_garbage < 4 || dev.stats().commands < 1)) {
    tld::Parser drain;
    host.read_until(drain, 0.05, [] { return false; });
  }
  EXPECT_EQ(dev.stats().command_garbage, 4u);
  EXPECT_EQ(dev.stats().commands, 1u);
  EXPECT_EQ(dev.stats().bytes_received, 9u);
}

TEST(VirtualDevice, ThePublishedFirmwareRepeatsItsFrameAndIgnoresCommands) {
  VirtualDeviceOptions o;
  o.firmware = FirmwareProfile::kPublished;
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  std::mutex mu;
  std::vector<std::array<std::uint16_t, tld::kPixels>> cycles;
  dev.on_wire([&](const WireTruth& w) {
    std::lock_guard lock(mu);
    if (w.kind == WireTruth::Kind::kPublishedCycle) cycles.push_back(w.cycle->distance);
  });
  dev.start();
  EXPECT_EQ(dev.firmware(), FirmwareProfile::kPublished);
  Host host(dev.path());
  ASSERT_TRUE(host.ok());
  host.send(tld::cmd_laser(false));  // ignored: it keeps sending
  host.send(tld::cmd_stream_mode(tld::StreamMode::Raw));
  tld::Parser parser;
  std::vector<tld::DistanceFrame> frames;
  host.read_until(parser, 5.0, [&] {
    while (auto f = parser.next_distance()) frames.push_back(*f);
    std::lock_guard lock(mu);
    return cycles.size() >= 4 && frames.size() >= 60;
  });
  ASSERT_GE(frames.size(), 60u);    // about 365 frames a second against about 10 updates
  EXPECT_FALSE(parser.next_set());  // never a raw frame
  EXPECT_EQ(parser.stats().raw_frames, 0u);
  std::size_t repeats = 0;
  for (std::size_t i = 1; i < frames.size(); ++i) repeats += frames[i].distance == frames[i - 1].distance ? 1 : 0;
  EXPECT_GT(repeats, frames.size() * 8 / 10);
  // Every frame is a cycle's words or a tear between two.
  std::lock_guard lock(mu);
  std::size_t known = 0;
  for (const auto& f : frames) {
    for (const auto& c : cycles) known += f.distance == c ? 1 : 0;
  }
  EXPECT_GE(known + 2 * cycles.size(), frames.size());
  // The target is 0.5 m away: 5000 units of 0.1 mm on the axis.
  EXPECT_NEAR(cycles.back()[136], 5000, 300);
  const auto st = dev.stats();
  EXPECT_EQ(st.commands, 2u);
  EXPECT_EQ(st.commands_ignored, 2u);
  EXPECT_TRUE(dev.laser_on());
}

TEST(VirtualDevice, SequenceModeLaserOffIsSilent) {
  VirtualDeviceOptions o;
  o.laser_on = false;
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()), o);
  dev.start();
  Host host(dev.path());
  tld::Parser parser;
  std::size_t bytes = 0;
  host.read_until(
      parser, 0.3, [] { return false; }, &bytes);
  EXPECT_EQ(bytes, 0u);
  host.send(tld::cmd_laser(true));
  std::size_t n = 0;
  host.read_until(parser, 2.0, [&] { return (n += take_sets(parser).size()) >= 2; });
  EXPECT_GE(n, 2u);
  host.send(tld::cmd_laser(false));
  host.read_until(parser, 0.15, [] { return false; });  // what was in flight
  bytes = 0;
  host.read_until(
      parser, 0.3, [] { return false; }, &bytes);
  EXPECT_EQ(bytes, 0u);
  EXPECT_FALSE(dev.laser_on());
}

TEST(VirtualDevice, StallHoldsTheLink) {
  VirtualDevice dev(SimulatedSystem::from_file(scene_path()));
  dev.start();
  Host host(dev.path());
  tld::Parser parser;
  host.read_until(parser, 0.2, [] { return false; });
  dev.stall(1.0);
  // Drain what was in the pty (or in flight) when the stall began; on a loaded
  // machine the device thread may have been mid-write. Then the link is quiet.
  host.read_until(parser, 0.15, [] { return false; });
  std::size_t bytes = 0;
  host.read_until(
      parser, 0.4, [] { return false; }, &bytes);
  EXPECT_LT(bytes, 4096u);  // at most one write that was already under way
  bytes = 0;
  host.read_until(
      parser, 5.0, [&] { return bytes > 10000u; }, &bytes);  // the stream resumes
  EXPECT_GT(bytes, 10000u);
  EXPECT_GT(dev.stats().frames_overflowed, 0u);
}

TEST(VirtualDevice, BadPortsAndSensorsAreClearErrors) {
  EXPECT_THROW(VirtualDevice::from_port("/dev/ttyUSB0"), std::invalid_argument);
  EXPECT_THROW(VirtualDevice::from_port("sim:"), std::invalid_argument);
  EXPECT_THROW(VirtualDevice::from_port("sim:/nonexistent.yaml"), ConfigError);
  try {
    (void)VirtualDevice::from_port("sim:" + scene_path() + "#nobody");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("laser"), std::string::npos);  // names the sensors there are
  }
  auto ok = VirtualDevice::from_port("sim:" + scene_path() + "#laser");
  EXPECT_EQ(ok->sensor_index(), 0u);
}
