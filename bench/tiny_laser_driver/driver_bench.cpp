// SPDX-License-Identifier: Apache-2.0
// Host cost per raw set, stage by stage, on one core:
//   Parse                 bytes (4 KiB reads, as a serial port returns them) -> RawSet
//   ParseSelectCalibrate  + per pixel: read-out selection, calibration model, status, reflectance
//   DriverNodePerSet      the driver node's own I/O step: parse, process, build RawScan, LineScan and
//                         LaserScan, publish to a subscriber and deliver (what a robot pays)
// Reference, in the same run:
//   PublicDriverFormula   the public driver's per-pixel arithmetic (k = b/(a+b), degree-6 polynomial,
//                         temperature term, its validity rule) over the same set, nothing else
// and every result carries the link's own time per set (5 x 1,096 bytes at 2 Mbaud, 8N1) as
// wire_us. Quote CPU time: on a shared machine wall time includes other processes' turns.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/public_driver_sensors.hpp>

#include "synthetic_raw_set.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace tt = tinyline::tiny_laser_driver::testing;
namespace bus = tinyline::bus;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr double kWireUs = 5 * 1096 * 10 / 2e6 * 1e6;  // 27,400 us per raw set on the wire

// A varied scene: ratios over the calibrated range, light from too dark to
// saturated at the top read-outs (so selection falls back on some pixels).
Bytes make_set(int seed) { return tt::varied_set(seed, 455); }

void wire_counters(benchmark::State& state) { state.counters["wire_us"] = kWireUs; }

void feed_in_reads(tl::Parser& parser, const Bytes& bytes) {
  constexpr std::size_t kRead = 4096;
  for (std::size_t at = 0; at < bytes.size(); at += kRead) {
    parser.feed({bytes.data() + at, std::min(kRead, bytes.size() - at)});
  }
}

void BM_Parse(benchmark::State& state) {
  const Bytes set = make_set(1);
  tl::Parser parser;
  for (auto _ : state) {
    feed_in_reads(parser, set);
    auto s = parser.next_set();
    benchmark::DoNotOptimize(s);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * set.size()));
  wire_counters(state);
}
BENCHMARK(BM_Parse);

void BM_ParseSelectCalibrate(benchmark::State& state) {
  const Bytes set = make_set(1);
  tl::Parser parser;
  const tl::ScanProcessor proc(*tl::public_driver_calibration("K"), {});
  tl::ProcessedScan out;
  int valid = 0;
  for (auto _ : state) {
    feed_in_reads(parser, set);
    auto s = parser.next_set();
    proc.process(*s, 0.0, out);
    valid = out.valid;
    benchmark::DoNotOptimize(out);
  }
  state.counters["valid_pixels"] = valid;
  wire_counters(state);
}
BENCHMARK(BM_ParseSelectCalibrate);

// The public driver's arithmetic per pixel and read-out (its loop keeps the last valid read-out).
void BM_PublicDriverFormula(benchmark::State& state) {
  const Bytes bytes = make_set(1);
  tl::Parser parser;
  parser.feed(bytes);
  const tl::RawSet set = *parser.next_set();
  const double poly[7] = {2.147918234375362e+06, -7.736068312640203e+06, 1.154494186428487e+07, -9.137795412258314e+06,
                          4.045684724836031e+06, -9.494901699902674e+05, 9.219599710241470e+04};
  std::vector<double> dist(tl::kPixels), refl(tl::kPixels);
  for (auto _ : state) {
    for (const auto& f : set.frames) {
      const double temp = (440.0 - f.temperature_decic) * 0.05623;
      for (std::size_t i = 0; i < tl::kPixels; ++i) {
        const double bot = f.a[i] / 10.0, top = f.b[i] / 10.0;
        const double k = top / (bot + top);
        double d = 0.0;
        if (bot <= 240 && bot >= 0 && bot + top > 10 + (f.pulses / 10) * 0.4) {
          d = ((((((poly[0] * k + poly[1]) * k + poly[2]) * k + poly[3]) * k + poly[4]) * k + poly[5]) * k + poly[6]) +
              temp;
        }
        d = d > 0 ? d : 0;
        if (bot > 10 && top > 10 && bot < 230 && top < 230 && d != 0) {
          dist[i] = d;
          refl[i] = d * d * (bot + top) / (f.pulses / 10);
        }
      }
    }
    benchmark::DoNotOptimize(dist.data());
    benchmark::DoNotOptimize(refl.data());
  }
  wire_counters(state);
}
BENCHMARK(BM_PublicDriverFormula);

// The driver node's I/O step on an in-memory link: parse + select + calibrate +
// build the three messages + publish + deliver to a subscriber.
void BM_DriverNodePerSet(benchmark::State& state) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  auto ctx = bus::Context::create(co);
  ctx->clock().set_sim_time(bus::Time::from_seconds(1.0));
  bus::DeterministicExecutor ex(ctx->clock());
  auto link = tl::io::MemoryLink::create("bench");
  tl::io::register_memory_link("bench", link);
  bus::NodeOptions o;
  o.context = ctx;
  o.name = "laser";
  o.param("port", std::string("mem:bench")).param("calibration", std::string("public:K")).param("threaded", false);
  auto driver = std::make_shared<tl::LaserDriver>(o);
  bus::NodeOptions lo;
  lo.context = ctx;
  lo.name = "listener";
  auto listener = std::make_shared<bus::Node>(lo);
  std::size_t got = 0;
  auto sub = listener->create_subscription<tinyline::tinyline_msgs::msg::LineScan>(
      "/scan", bus::QoS::keep_last(10), [&](const tinyline::tinyline_msgs::msg::LineScan&) { ++got; });
  ex.add_node(driver);
  ex.add_node(listener);
  ex.spin_until_idle();
  driver->pump(std::chrono::milliseconds(0));  // connect
  // Two sets in turn: a set equal to the one before is a repeat, not a measurement.
  const Bytes sets[2] = {make_set(1), make_set(2)};
  std::size_t turn = 0;
  for (auto _ : state) {
    link->push(sets[turn++ % 2]);
    while (link->queued() > 0) driver->pump(std::chrono::milliseconds(0));
    ex.spin_until_idle();
  }
  if (got != static_cast<std::size_t>(state.iterations())) state.SkipWithError("scans lost");
  wire_counters(state);
  tl::io::unregister_memory_link("bench");
}
BENCHMARK(BM_DriverNodePerSet);

}  // namespace

BENCHMARK_MAIN();
