// End to end through the simulator's virtual device: the driver opens the
// device's pseudo-terminal (behind a stable symlink) exactly as it opens a
// real sensor, with its own I/O thread on the wall clock.
//
// Waiting is on conditions (a scan arrived, the driver reports N failed
// attempts), never a fixed sleep; the replug assertion uses the time the
// device came back and the time the first scan after it arrived.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include <sim/system.hpp>
#include <sim/virtual_device.hpp>
#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace sim = tinyline::sim;
namespace bus = tinyline::bus;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using tinyline::diagnostic_msgs::msg::DiagnosticArray;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::RawScan;
using Clock = std::chrono::steady_clock;

namespace {

constexpr auto kPatience = 60s;  // generous: the machine may be shared; a pass is usually a few seconds

struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/tinyline_e2e_XXXXXX";
    path = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string diag_value(const DiagnosticArray& d, const std::string& key) {
  for (const auto& s : d.status) {
    for (const auto& kv : s.values) {
      if (kv.key == key) return kv.value;
    }
  }
  return "";
}

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
  std::vector<Clock::time_point> scan_times;
  std::vector<std::shared_ptr<const RawScan>> raws;
  std::shared_ptr<const DiagnosticArray> last_diag;
  std::vector<double> truth;  // true range per pixel of the latest simulated set
  std::shared_ptr<bus::Subscription<LineScan>> s1;
  std::shared_ptr<bus::Subscription<RawScan>> s2;
  std::shared_ptr<bus::Subscription<DiagnosticArray>> s3;

  explicit Bench(sim::LinkFaults faults = {}) {
    system = sim::SimulatedSystem::from_file(TINYLINE_SOURCE_DIR "/sim/config/scenes/calibration_rail.yaml");
    sim::VirtualDeviceOptions o;
    o.link_path = (tmp.path / "ttyTINY0").string();
    o.faults = faults;
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
    d.param("port", o.link_path).param("calibration", std::string("default")).param("focal_mm", 8.0)
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
      scan_times.push_back(Clock::now());
      cv.notify_all();
    });
    s2 = listener->create_subscription<RawScan>("/raw", q, [this](const std::shared_ptr<const RawScan>& m) {
      std::lock_guard lk(mu);
      raws.push_back(m);
    });
    s3 = listener->create_subscription<DiagnosticArray>("/diagnostics", q,
                                                        [this](const std::shared_ptr<const DiagnosticArray>& m) {
                                                          std::lock_guard lk(mu);
                                                          last_diag = m;
                                                          cv.notify_all();
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
  std::size_t scan_count() {
    std::lock_guard lk(mu);
    return scans.size();
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
  const double rmse = std::sqrt(se / n), bias = sum / n;
  // The shipped calibration's held-out RMSE (config/calibration/README.md), with room for sampling.
  EXPECT_LT(rmse, 3.58 * 1.25) << "rmse " << rmse << " cm over " << n << " pixels";
  EXPECT_LT(std::abs(bias), 1.0) << "bias " << bias << " cm";
  EXPECT_GT(static_cast<double>(n) / seen, 0.9);
}

TEST(EndToEnd, OnePercentByteCorruptionCostsOnlyWholeSetsAndEveryOneIsCounted) {
  sim::LinkFaults faults;
  faults.byte_error_rate = 0.01;
  faults.seed = 11;
  Bench b(faults);
  ASSERT_TRUE(b.wait([&] { return b.scans.size() >= 150; }));
  // Freeze the link, let the driver read everything that was sent, then compare books.
  b.device->stall(3600.0);
  const sim::VirtualDeviceStats dev = b.device->stats();
  ASSERT_TRUE(b.wait([&] { return b.driver->status().bytes >= dev.bytes_sent; }));
  const tl::DriverStatus drv = b.driver->status();
  const auto& ps = drv.parser;
  EXPECT_EQ(drv.bytes, dev.bytes_sent);  // nothing lost between device and driver
  EXPECT_EQ(dev.bytes_overrun, 0u);
  EXPECT_TRUE(drv.connected);

  // Every set the device sent is either published whole or counted as incomplete.
  const std::uint64_t sets_sent = dev.frames_sent / 5;
  const std::uint64_t accounted = ps.sets + ps.dropped(tl::DropReason::kIncompleteSet);
  EXPECT_LE(accounted, sets_sent + 2);
  EXPECT_GE(accounted + 2, sets_sent);
  // The share lost is what the corruption predicts: a set is lost when a bit flip hits one of its
  // frames' header, index or ender bytes (always detected: 6 per frame) and at most also the packed
  // temperature/pulses word (8 per frame).
  const double q = static_cast<double>(dev.bytes_corrupted) / static_cast<double>(dev.bytes_sent);
  EXPECT_NEAR(q, 0.01, 0.002);
  const double lo = 1 - std::pow(1 - q, 30), hi = 1 - std::pow(1 - q, 40);
  const double lost = static_cast<double>(ps.dropped(tl::DropReason::kIncompleteSet)) / static_cast<double>(accounted);
  const double sigma = std::sqrt(hi * (1 - hi) / static_cast<double>(accounted));
  EXPECT_GT(lost, lo - 3 * sigma) << "lost " << lost << " of " << accounted << " sets";
  EXPECT_LT(lost, hi + 3 * sigma) << "lost " << lost << " of " << accounted << " sets";
  // Damage the framing cannot catch (pixel bytes) shows up as impossible values.
  EXPECT_GT(ps.impossible_values, 0u);

  ASSERT_TRUE(b.wait([&] { return b.scans.size() >= drv.scans_published; }));
  std::lock_guard lk(b.mu);
  EXPECT_EQ(b.scans.size(), ps.sets);
  for (const auto& s : b.scans) expect_whole(*s);
  for (const auto& r : b.raws) expect_whole(*r);
}

TEST(EndToEnd, UnplugAndReplugWhileStreamingResumesWithinASecond) {
  Bench b;
  ASSERT_TRUE(b.wait([&] { return b.scans.size() >= 10; }));
  b.device->unplug();
  // Wait until the driver has noticed, kept trying, and backed off to its longest wait.
  ASSERT_TRUE(b.wait([&] {
    return b.last_diag && diag_value(*b.last_diag, "state") == "disconnected" &&
           std::stoi(diag_value(*b.last_diag, "open_failures")) >= 5;
  }));
  const std::size_t before = b.scan_count();
  b.device->replug();
  const auto replugged = Clock::now();
  ASSERT_TRUE(b.wait([&] { return b.scans.size() > before; }));
  double resumed_s = 0;
  {
    std::lock_guard lk(b.mu);
    resumed_s = std::chrono::duration<double>(b.scan_times[before] - replugged).count();
    for (const auto& s : b.scans) expect_whole(*s);
    for (const auto& r : b.raws) expect_whole(*r);
  }
  EXPECT_LE(resumed_s, 1.0) << "publishing resumed " << resumed_s << " s after the device came back";
  const auto st = b.driver->status();
  EXPECT_EQ(st.disconnects, 1u);
  EXPECT_EQ(st.connects, 2u);
}
