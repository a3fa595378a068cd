// SPDX-License-Identifier: Apache-2.0
// End to end through the simulator: the driver opens the virtual device's
// pseudo-terminal (behind a stable symlink) exactly as it opens a real
// sensor (rail accuracy with its own I/O thread; unplug/replug stepped on a
// sim clock); the byte-corruption books are kept on a stepped sim clock
// (simulated sets on an in-memory link), so they are exact and load-free.
//
// Waiting is on conditions (a scan arrived, the driver reports N failed
// attempts) or a bounded number of steps, never a fixed sleep; the replug
// assertion adds the driver's reconnect delay in sim time to the link time of
// the bytes it read until the first whole set.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include <sim/firmware.hpp>
#include <sim/system.hpp>
#include <sim/virtual_device.hpp>
#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/testing.hpp>

#include <tiny_laser_driver/io/port.hpp>
#include <tiny_laser_driver/nodes/laser_driver.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace sim = tinyline::sim;
namespace bus = tinyline::bus;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::RawScan;

namespace {

constexpr auto kPatience = 60s;  // generous: the machine may be shared; a pass is usually a few seconds

using TempDir = tinyline::bus::testing::TempDir;

// The calibration rail scene (white paper at 0.5 m, 8 mm sensor) on a virtual
// device, and the driver reading it.
struct Bench {
  TempDir tmp;
  std::shared_ptr<sim::SimulatedSystem> system;
  std::unique_ptr<sim::VirtualDevice> device;
  std::shared_ptr<bus::Context> ctx;
  std::shared_ptr<tl::LaserDriver> driver;
  std::shared_ptr<bus::Node> listener;
  std::unique_ptr<bus::SingleThreadedExecutor> ex;
  std::thread spinner;

  std::mutex mu;
  std::condition_variable cv;
  std::vector<std::shared_ptr<const LineScan>> scans;
  std::vector<std::shared_ptr<const RawScan>> raws;
  std::vector<double> truth;  // true range per pixel of the latest simulated set
  std::shared_ptr<bus::Subscription<LineScan>> s1;
  std::shared_ptr<bus::Subscription<RawScan>> s2;

  explicit Bench(const std::string& scene = TINYLINE_SOURCE_DIR "/sim/config/scenes/calibration_rail.yaml") {
    system = sim::SimulatedSystem::from_file(scene);
    sim::VirtualDeviceOptions o;
    o.link_path = (tmp.path / "ttyTINY0").string();
    device = std::make_unique<sim::VirtualDevice>(system, o);
    device->on_set([this](const sim::SensorSet& s) {
      std::lock_guard lk(mu);
      truth.resize(s.truth.size());
      for (std::size_t p = 0; p < s.truth.size(); ++p) truth[p] = s.truth[p].range_m;
    });
    device->start();

    ctx = bus::Context::create({bus::ClockType::Wall, std::make_shared<bus::CaptureSink>()});
    bus::NodeOptions d;
    d.context = ctx;
    d.name = "laser";
    d.param("port", o.link_path)
        .param("calibration", std::string("default"))
        .param("focal_mm", 8.0)
        .param("diagnostics_period_s", 0.1);
    driver = std::make_shared<tl::LaserDriver>(d);
    bus::NodeOptions l;
    l.context = ctx;
    l.name = "listener";
    listener = std::make_shared<bus::Node>(l);
    const auto q = bus::QoS::keep_last(10000);
    s1 = listener->create_subscription<LineScan>("/scan", q, [this](const std::shared_ptr<const LineScan>& m) {
      std::lock_guard lk(mu);
      scans.push_back(m);
      cv.notify_all();
    });
    s2 = listener->create_subscription<RawScan>("/raw", q, [this](const std::shared_ptr<const RawScan>& m) {
      std::lock_guard lk(mu);
      raws.push_back(m);
    });
    ex = std::make_unique<bus::SingleThreadedExecutor>(ctx->clock());
    ex->add_node(driver);
    ex->add_node(listener);
    spinner = std::thread([this] { ex->spin(); });
  }
  ~Bench() {
    ex->stop();
    spinner.join();
    driver->on_stop();
    device->stop();
  }

  template <class Pred>
  bool wait(Pred pred) {
    std::unique_lock lk(mu);
    return cv.wait_for(lk, kPatience, pred);
  }
};

void expect_whole(const LineScan& s) {
  EXPECT_EQ(s.distance_m.size(), tl::kPixels);
  EXPECT_EQ(s.status.size(), tl::kPixels);
  EXPECT_EQ(s.angles.size(), tl::kPixels);
}

void expect_whole(const RawScan& r) {
  std::string why;
  EXPECT_TRUE(tl::from_raw_scan(r, &why).has_value()) << why;
  EXPECT_EQ(r.pulses.size(), 5u);
}

// The driver (threaded: false, the shipped default calibration) on the stepped
// sim-time graph of bus/testing.hpp, with every calibrated and raw scan it
// publishes kept.
struct SteppedDriver : bus::testing::NodeRig {
  explicit SteppedDriver(const std::string& port) : NodeRig({}, bus::Time::from_seconds(10.0)) {
    bus::NodeOptions d;
    d.context = ctx;
    d.name = "laser";
    d.param("port", port).param("calibration", std::string("default")).param("focal_mm", 8.0).param("threaded", false);
    driver = add(std::make_shared<tl::LaserDriver>(d));
    ex.spin_until_idle();  // on_start
  }
  std::shared_ptr<tl::LaserDriver> driver;
  std::vector<std::shared_ptr<const LineScan>>& scans = collect<LineScan>("/scan");
  std::vector<std::shared_ptr<const RawScan>>& raws = collect<RawScan>("/raw");
};

}  // namespace

TEST(EndToEnd, RailScansMatchGroundTruthWithinTheCalibrationError) {
  Bench b;
  ASSERT_TRUE(b.wait([&] { return b.scans.size() >= 30; })) << "no scans from the virtual device";
  std::vector<std::shared_ptr<const LineScan>> scans;
  std::vector<double> truth;
  {
    std::lock_guard lk(b.mu);
    scans = b.scans;
    truth = b.truth;  // the scene is static: every set has the same true ranges
  }
  ASSERT_EQ(truth.size(), tl::kPixels);
  double se = 0, sum = 0;
  int n = 0, seen = 0;
  for (const auto& s : scans) {
    expect_whole(*s);
    for (std::size_t p = tl::kDarkPixels; p < tl::kPixels - tl::kDarkPixels; ++p) {
      if (!std::isfinite(truth[p])) continue;
      ++seen;
      if (s->status[p] != LineScan::STATUS_VALID) continue;
      const double e = 100.0 * (s->distance_m[p] - truth[p]);
      se += e * e;
      sum += e;
      ++n;
    }
  }
  int by_status[6] = {0, 0, 0, 0, 0, 0};
  for (const auto& s : scans) {
    for (std::size_t p = tl::kDarkPixels; p < tl::kPixels - tl::kDarkPixels; ++p) {
      if (std::isfinite(truth[p]) && s->status[p] < 6) ++by_status[s->status[p]];
    }
  }
  const double rmse = std::sqrt(se / n), bias = sum / n;
  std::printf("rail, thesis firmware: %zu scans, statuses valid %d saturated %d too dark %d out of range %d stale %d\n",
              scans.size(), by_status[0], by_status[1], by_status[2], by_status[4], by_status[5]);
  // The shipped calibration's held-out RMSE (config/calibration/README.md), with room for sampling.
  EXPECT_LT(rmse, 3.28 * 1.25) << "rmse " << rmse << " cm over " << n << " pixels";
  EXPECT_LT(std::abs(bias), 1.0) << "bias " << bias << " cm";
  EXPECT_GT(static_cast<double>(n) / seen, 0.9);
}

TEST(EndToEnd, ThePublishedFirmwaresScansMatchGroundTruthWithDefaultParameters) {
  // The scene picks the published firmware: distance frames in 0.1 mm, each
  // repeated about 36 times. The driver is not told: one scan per buffer update.
  Bench b(TINYLINE_SOURCE_DIR "/sim/config/scenes/calibration_rail_published.yaml");
  ASSERT_TRUE(b.wait([&] { return b.scans.size() >= 12; })) << "no scans from the virtual device";
  std::vector<std::shared_ptr<const LineScan>> scans;
  std::vector<double> truth;
  {
    std::lock_guard lk(b.mu);
    scans = b.scans;
    truth = b.truth;
  }
  const auto cycles = b.device->stats().cycles;
  EXPECT_LE(scans.size(), cycles) << "a repeated frame was published as a new measurement";
  EXPECT_TRUE(b.raws.empty());
  std::vector<double> errors;
  int seen = 0;
  for (const auto& s : scans) {
    for (std::size_t p = tl::kDarkPixels; p < tl::kPixels - tl::kDarkPixels; ++p) {
      if (!std::isfinite(truth[p])) continue;
      ++seen;
      if (s->status[p] == LineScan::STATUS_VALID) errors.push_back(100.0 * (s->distance_m[p] - truth[p]));
    }
  }
  ASSERT_FALSE(errors.empty());
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2];
  const double p90 = std::max(std::abs(errors[errors.size() / 20]), std::abs(errors[errors.size() * 19 / 20]));
  std::printf("published firmware, %zu scans of %llu cycles: median error %.2f cm, 90%% within %.2f cm, valid %.3f\n",
              scans.size(), static_cast<unsigned long long>(cycles), median, p90,
              static_cast<double>(errors.size()) / seen);
  // One polynomial for all pixels (the firmware's): each pixel's own sensitivity ratio is a fixed offset.
  EXPECT_LT(std::abs(median), 1.5) << "median error " << median << " cm";
  EXPECT_LT(p90, 8.0) << "90% of the errors within " << p90 << " cm";
  EXPECT_GT(static_cast<double>(errors.size()) / seen, 0.9);
}

TEST(EndToEnd, OnePercentByteCorruptionCostsOnlyWholeSetsAndEveryOneIsCounted) {
  // Stepped, not streamed: the simulator measures sets of the calibration rail
  // back to back on its own time line, each frame goes on an in-memory link
  // when its bytes would have finished on the wire, with the virtual device's
  // fault model (a byte is hit with probability 1%, one random bit flips), and
  // the driver (threaded: false) reads it at that sim time. Nothing depends on
  // the wall clock or the machine's load, and the test knows every flipped
  // byte, so it predicts the books exactly.
  const auto system = sim::SimulatedSystem::from_file(TINYLINE_SOURCE_DIR "/sim/config/scenes/calibration_rail.yaml");
  const auto& sensor = system->sensor(0).params();
  const std::vector<int>& schedule = sensor.acquisition.raw_pulses;

  const auto link = tl::io::MemoryLink::create("e2e_corruption");
  tl::io::register_memory_link("e2e_corruption", link);
  SteppedDriver h("mem:e2e_corruption");
  auto& ctx = h.ctx;
  auto& ex = h.ex;
  auto& driver = h.driver;
  auto& scans = h.scans;
  auto& raws = h.raws;
  driver->pump(0ms);  // connects
  ASSERT_TRUE(driver->status().connected);

  constexpr int kSets = 200;
  constexpr double kErrorRate = 0.01;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double byte_s = tl::byte_time_s(2'000'000.0);
  std::uint64_t bytes_sent = 0, bytes_corrupted = 0;
  // The prediction, from the flipped bytes alone.
  int lost = 0, header_hit_frames = 0, ender_hit_frames = 0;
  std::set<std::uint64_t> lost_sets;
  double t_shared = 0.0;
  for (int k = 0; k < kSets; ++k) {
    const sim::SensorSet set = system->measure(0, t_shared, schedule, static_cast<std::uint64_t>(k));
    t_shared = set.t_end_s - system->sensor_time(0.0);
    bool set_lost = false;
    int prev_pulses = 0;
    for (const tl::RawFrame& f : sim::raw_frames(set)) {
      std::vector<std::uint8_t> bytes;
      tl::encode_raw_frame(f, bytes);
      bool header = false, index = false, ender = false;
      for (std::size_t i = 0; i < bytes.size(); ++i) {
        if (uniform(rng) >= kErrorRate) continue;
        bytes[i] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
        ++bytes_corrupted;
        header = header || i < 2;
        index = index || i == 2 || i == 3;
        ender = ender || i >= bytes.size() - 2;
      }
      // The pulses the parser will read from the (maybe flipped) packed word.
      const int pulses = (bytes[4] | (bytes[5] << 8)) % 100 * 10;
      const bool pulses_broken = pulses == 0 || pulses <= prev_pulses;
      prev_pulses = pulses;
      set_lost = set_lost || header || index || ender || pulses_broken;
      header_hit_frames += header ? 1 : 0;
      ender_hit_frames += (ender && !header) ? 1 : 0;
      bytes_sent += bytes.size();
      // The frame's bytes have left the wire when its read-out is done and it has been sent.
      ex.advance_to(ctx->clock().now() + bus::from_seconds(static_cast<double>(bytes.size()) * byte_s));
      link->push(bytes);
      driver->pump(0ms);
      ex.spin_until_idle();
    }
    if (set_lost) {
      ++lost;
      lost_sets.insert(static_cast<std::uint64_t>(k));
    }
  }
  tl::io::unregister_memory_link("e2e_corruption");

  const tl::DriverStatus drv = driver->status();
  const auto& ps = drv.parser;
  EXPECT_EQ(drv.bytes, bytes_sent);
  EXPECT_TRUE(drv.connected);
  EXPECT_NEAR(static_cast<double>(bytes_corrupted) / static_cast<double>(bytes_sent), kErrorRate, 0.001);
  // The books: every set sent is published whole or counted incomplete, once.
  EXPECT_EQ(ps.sets + ps.dropped(tl::DropReason::kIncompleteSet), static_cast<std::uint64_t>(kSets));
  EXPECT_EQ(ps.dropped(tl::DropReason::kIncompleteSet), static_cast<std::uint64_t>(lost))
      << "the sets lost are those with a flip in a frame's header, index or ender, or a packed word whose pulses no "
         "longer rise";
  EXPECT_GT(lost, kSets / 5);  // about 1 - 0.99^30 of them: the test exercises the damage
  // Frames lost, by reason: a hit header makes the frame garbage, a hit ender a bad ender.
  EXPECT_EQ(ps.dropped(tl::DropReason::kBadEnder), static_cast<std::uint64_t>(ender_hit_frames));
  EXPECT_EQ(ps.dropped(tl::DropReason::kGarbage),
            static_cast<std::uint64_t>(header_hit_frames) * tl::kRawFrameBytes +
                static_cast<std::uint64_t>(ender_hit_frames) * (tl::kRawFrameBytes - 2));
  // Damage the framing cannot catch (pixel bytes) shows up as impossible values.
  EXPECT_GT(ps.impossible_values, 0u);

  // Only the undamaged sets were published, whole, in order.
  ASSERT_EQ(scans.size(), ps.sets);
  ASSERT_EQ(raws.size(), ps.sets);
  EXPECT_EQ(drv.scans_published, ps.sets);
  std::vector<std::uint64_t> expect_index;
  for (std::uint64_t k = 0; k < kSets; ++k) {
    if (!lost_sets.contains(k)) expect_index.push_back(k);
  }
  std::vector<std::uint64_t> got_index;
  for (const auto& s : scans) {
    expect_whole(*s);
    got_index.push_back(s->set_index);
  }
  EXPECT_EQ(got_index, expect_index);  // the set index counts the lost ones too
  for (const auto& r : raws) expect_whole(*r);
}

TEST(EndToEnd, UnplugAndReplugWhileStreamingResumesWithinASecond) {
  // The virtual device streams on its pty in real time; the driver runs on a
  // sim clock (threaded: false), 10 ms of sim time per step. The resume time
  // has two parts, neither read off the wall clock: the driver's reconnect
  // delay after the device is back (sim time: its backoff schedule), and the
  // link time of the bytes it then read until the first whole set was
  // published (bytes x 10 bits at 2 Mbaud: the partial set the device was
  // sending when the port opened, then one whole set).
  TempDir tmp;
  const auto system = sim::SimulatedSystem::from_file(TINYLINE_SOURCE_DIR "/sim/config/scenes/calibration_rail.yaml");
  sim::VirtualDeviceOptions o;
  o.link_path = (tmp.path / "ttyTINY0").string();
  sim::VirtualDevice device(system, o);
  device.start();

  SteppedDriver h(o.link_path);
  auto& ctx = h.ctx;
  auto& ex = h.ex;
  auto& driver = h.driver;
  auto& scans = h.scans;
  auto& raws = h.raws;
  auto step = [&] {
    ex.advance_to(ctx->clock().now() + 10ms);
    driver->pump(driver->status().connected ? 100ms : 0ms);
    ex.spin_until_idle();
  };
  // Bounded loops: every wait is a number of steps, never an open-ended sleep.
  auto step_until = [&](auto pred, int max_steps) {
    for (int i = 0; i < max_steps; ++i) {
      if (pred()) return true;
      step();
    }
    return pred();
  };

  ASSERT_TRUE(step_until([&] { return scans.size() >= 10; }, 3000)) << "no scans from the virtual device";
  device.unplug();
  // The driver notices, keeps trying, and backs off to its longest wait.
  ASSERT_TRUE(step_until(
      [&] {
        const auto st = driver->status();
        return !st.connected && st.open_failures >= 5;
      },
      3000));
  const std::size_t before = scans.size();
  const std::uint64_t bytes_before = driver->status().bytes;
  device.replug();
  const bus::Time replugged = ctx->clock().now();
  ASSERT_TRUE(step_until([&] { return driver->status().connects == 2; }, 3000)) << "never reconnected";
  const double reconnect_s = bus::to_seconds(ctx->clock().now() - replugged);
  ASSERT_TRUE(step_until([&] { return scans.size() > before; }, 3000)) << "publishing never resumed";
  const double link_s = static_cast<double>(driver->status().bytes - bytes_before) * tl::byte_time_s(2'000'000.0);
  const double resumed_s = reconnect_s + link_s;
  RecordProperty("reconnect_s", std::to_string(reconnect_s));
  RecordProperty("link_s", std::to_string(link_s));
  EXPECT_LE(reconnect_s, 0.5) << "reconnect_max_s is 0.5 s";
  EXPECT_LE(resumed_s, 1.0) << "publishing resumed " << resumed_s << " s after the device came back (reconnect "
                            << reconnect_s << " s, then " << link_s << " s of bytes)";
  for (const auto& s : scans) expect_whole(*s);
  for (const auto& r : raws) expect_whole(*r);
  const auto st = driver->status();
  EXPECT_EQ(st.disconnects, 1u);
  EXPECT_EQ(st.connects, 2u);
  device.stop();
}
