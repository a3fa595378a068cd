// SPDX-License-Identifier: Apache-2.0
// The in-process bus against its floor and a peer, in one run.
//
//   floor:  a direct call (same thread); a lock-free single-slot handoff
//           between two spinning threads (across threads)
//   peer:   ZeroMQ inproc PAIR sockets (the lightest Debian middleware)
//   bus:    tinyline publish -> subscription callback
//
// Latency benchmarks record every one-way latency and report p50/p99 as
// counters (Google Benchmark's own time is the mean per iteration).
#include <benchmark/benchmark.h>
#include <zmq.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <thread>
#include <vector>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

using namespace tinyline;
using StringMsg = std_msgs::msg::String;
using Clock = std::chrono::steady_clock;

namespace {

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

void report_percentiles(benchmark::State& state, std::vector<std::int64_t>& lat) {
  if (lat.empty()) return;
  std::sort(lat.begin(), lat.end());
  state.counters["p50_us"] = static_cast<double>(lat[lat.size() / 2]) / 1e3;
  state.counters["p99_us"] = static_cast<double>(lat[lat.size() * 99 / 100]) / 1e3;
}

std::shared_ptr<bus::Context> quiet_context(bus::ClockType clock = bus::ClockType::Wall) {
  bus::ContextOptions o;
  o.clock = clock;
  o.log_sink = std::make_shared<bus::CaptureSink>();
  return bus::Context::create(o);
}

std::shared_ptr<bus::Node> node(const std::shared_ptr<bus::Context>& ctx, const std::string& name) {
  bus::NodeOptions o;
  o.name = name;
  o.context = ctx;
  return std::make_shared<bus::Node>(o);
}

std::unique_ptr<StringMsg> payload(std::size_t bytes) {
  auto m = std::make_unique<StringMsg>();
  m->data.assign(bytes, 'x');
  return m;
}

// ---------------------------------------------------------------------------- same thread

void BM_Floor_DirectCall(benchmark::State& state) {
  std::size_t seen = 0;
  std::function<void(const std::shared_ptr<const StringMsg>&)> cb = [&](const auto& m) { seen += m->data.size(); };
  for (auto _ : state) {
    std::shared_ptr<const StringMsg> m = payload(static_cast<std::size_t>(state.range(0)));
    cb(m);
  }
  benchmark::DoNotOptimize(seen);
}
BENCHMARK(BM_Floor_DirectCall)->Arg(64)->Arg(8192);

void BM_Bus_SameThread(benchmark::State& state) {
  auto ctx = quiet_context(bus::ClockType::Sim);
  bus::DeterministicExecutor ex(ctx->clock());
  auto n = node(ctx, "n");
  std::size_t seen = 0;
  auto sub = n->create_subscription<StringMsg>("t", bus::QoS::keep_last(10),
                                               [&](const StringMsg& m) { seen += m.data.size(); });
  auto pub = n->create_publisher<StringMsg>("t");
  ex.add_node(n);
  for (auto _ : state) {
    pub->publish(payload(static_cast<std::size_t>(state.range(0))));
    ex.spin_until_idle();
  }
  benchmark::DoNotOptimize(seen);
}
BENCHMARK(BM_Bus_SameThread)->Arg(64)->Arg(8192);

// ---------------------------------------------------------------------------- the publisher's own costs
//
// What publish() spends besides the queue (same thread): the wall-clock read
// for MessageInfo, and publish() of one shared message to a topic without
// subscribers (that clock read, the sequence number, the subscription
// snapshot under the topic's lock, the reference count).

void BM_Cost_ClockRead(benchmark::State& state) {
  auto ctx = quiet_context();
  for (auto _ : state) benchmark::DoNotOptimize(ctx->clock().now());
}
BENCHMARK(BM_Cost_ClockRead);

void BM_Cost_PublishNoSubscriber(benchmark::State& state) {
  auto ctx = quiet_context();
  auto n = node(ctx, "n");
  auto pub = n->create_publisher<StringMsg>("t");
  auto msg = std::shared_ptr<const StringMsg>(payload(64));
  for (auto _ : state) pub->publish(msg);
}
BENCHMARK(BM_Cost_PublishNoSubscriber);

// ---------------------------------------------------------------------------- across threads, latency

constexpr int kLatencySamples = 20000;

void BM_Floor_LockFreeHandoff(benchmark::State& state) {
  // One slot, two spinning threads: the cost of moving a pointer between cores.
  std::atomic<StringMsg*> slot{nullptr};
  std::atomic<bool> stop{false};
  std::vector<std::int64_t> lat;
  lat.reserve(kLatencySamples);
  std::atomic<int> received{0};
  std::thread consumer([&] {
    while (!stop.load(std::memory_order_relaxed)) {
      StringMsg* m = slot.exchange(nullptr, std::memory_order_acquire);
      if (m == nullptr) continue;
      const std::int64_t sent = std::stoll(m->data.substr(0, 20));
      lat.push_back(now_ns() - sent);
      delete m;
      received.fetch_add(1, std::memory_order_release);
    }
  });
  int sent = 0;
  for (auto _ : state) {
    auto m = payload(static_cast<std::size_t>(state.range(0)));
    const std::string stamp = std::to_string(now_ns());
    std::memcpy(m->data.data(), stamp.data(), stamp.size());
    m->data[stamp.size()] = ' ';
    slot.store(m.release(), std::memory_order_release);
    ++sent;
    while (received.load(std::memory_order_acquire) < sent) {}
  }
  stop.store(true);
  consumer.join();
  report_percentiles(state, lat);
}
BENCHMARK(BM_Floor_LockFreeHandoff)->Arg(64)->Arg(8192)->Iterations(kLatencySamples)->UseRealTime();

void BM_Bus_AcrossThreads(benchmark::State& state) {
  auto ctx = quiet_context();
  auto src = node(ctx, "src");
  auto dst = node(ctx, "dst");
  std::vector<std::int64_t> lat;
  lat.reserve(kLatencySamples);
  std::atomic<int> received{0};
  auto sub = dst->create_subscription<StringMsg>("t", bus::QoS::keep_last(10), [&](const StringMsg& m) {
    lat.push_back(now_ns() - std::stoll(m.data.substr(0, 20)));
    received.fetch_add(1, std::memory_order_release);
  });
  auto pub = src->create_publisher<StringMsg>("t");
  bus::SingleThreadedExecutor ex(ctx->clock());
  ex.add_node(dst);
  std::thread spinner([&] { ex.spin(); });
  int sent = 0;
  for (auto _ : state) {
    auto m = payload(static_cast<std::size_t>(state.range(0)));
    const std::string stamp = std::to_string(now_ns());
    std::memcpy(m->data.data(), stamp.data(), stamp.size());
    m->data[stamp.size()] = ' ';
    pub->publish(std::move(m));
    ++sent;
    while (received.load(std::memory_order_acquire) < sent) {}
  }
  ex.stop();
  spinner.join();
  report_percentiles(state, lat);
}
BENCHMARK(BM_Bus_AcrossThreads)->Arg(64)->Arg(8192)->Iterations(kLatencySamples)->UseRealTime();

void BM_ZeroMQ_InprocAcrossThreads(benchmark::State& state) {
  void* zctx = zmq_ctx_new();
  void* tx = zmq_socket(zctx, ZMQ_PAIR);
  void* rx = zmq_socket(zctx, ZMQ_PAIR);
  zmq_bind(rx, "inproc://bench");
  zmq_connect(tx, "inproc://bench");
  std::vector<std::int64_t> lat;
  lat.reserve(kLatencySamples);
  std::atomic<int> received{0};
  std::atomic<bool> stop{false};
  std::thread consumer([&] {
    std::vector<char> buf(static_cast<std::size_t>(state.range(0)) + 64);
    zmq_pollitem_t item{rx, 0, ZMQ_POLLIN, 0};
    while (!stop.load()) {
      if (zmq_poll(&item, 1, 10) <= 0) continue;
      const int n = zmq_recv(rx, buf.data(), buf.size(), 0);
      if (n <= 0) continue;
      lat.push_back(now_ns() - std::stoll(std::string(buf.data(), 20)));
      received.fetch_add(1, std::memory_order_release);
    }
  });
  int sent = 0;
  std::string data(static_cast<std::size_t>(state.range(0)), 'x');
  for (auto _ : state) {
    const std::string stamp = std::to_string(now_ns());
    std::memcpy(data.data(), stamp.data(), stamp.size());
    data[stamp.size()] = ' ';
    zmq_send(tx, data.data(), data.size(), 0);
    ++sent;
    while (received.load(std::memory_order_acquire) < sent) {}
  }
  stop.store(true);
  consumer.join();
  zmq_close(tx);
  zmq_close(rx);
  zmq_ctx_term(zctx);
  report_percentiles(state, lat);
}
BENCHMARK(BM_ZeroMQ_InprocAcrossThreads)->Arg(64)->Arg(8192)->Iterations(kLatencySamples)->UseRealTime();

// ---------------------------------------------------------------------------- throughput

constexpr int kBurst = 200000;

void BM_Bus_Throughput(benchmark::State& state) {
  // A publisher thread sends a burst of small messages through one topic to a
  // subscriber on an executor thread; reliable QoS, so every one arrives.
  auto ctx = quiet_context();
  auto src = node(ctx, "src");
  auto dst = node(ctx, "dst");
  std::atomic<int> received{0};
  auto sub = dst->create_subscription<StringMsg>(
      "t", bus::QoS::reliable(4096), [&](const StringMsg&) { received.fetch_add(1, std::memory_order_relaxed); });
  auto pub = src->create_publisher<StringMsg>("t");
  bus::SingleThreadedExecutor ex(ctx->clock());
  ex.add_node(dst);
  std::thread spinner([&] { ex.spin(); });
  std::int64_t total = 0;
  for (auto _ : state) {
    const int start = received.load();
    for (int i = 0; i < kBurst; ++i) pub->publish(payload(16));
    while (received.load(std::memory_order_acquire) < start + kBurst) {}
    total += kBurst;
  }
  ex.stop();
  spinner.join();
  state.counters["msgs_per_s"] = benchmark::Counter(static_cast<double>(total), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Bus_Throughput)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);

void BM_ZeroMQ_Throughput(benchmark::State& state) {
  void* zctx = zmq_ctx_new();
  void* tx = zmq_socket(zctx, ZMQ_PAIR);
  void* rx = zmq_socket(zctx, ZMQ_PAIR);
  const int hwm = 0;  // unbounded: nothing dropped, as with the bus's reliable queue
  zmq_setsockopt(tx, ZMQ_SNDHWM, &hwm, sizeof(hwm));
  zmq_setsockopt(rx, ZMQ_RCVHWM, &hwm, sizeof(hwm));
  zmq_bind(rx, "inproc://tput");
  zmq_connect(tx, "inproc://tput");
  std::int64_t total = 0;
  for (auto _ : state) {
    std::thread consumer([&] {
      char buf[64];
      for (int i = 0; i < kBurst; ++i) zmq_recv(rx, buf, sizeof(buf), 0);
    });
    const std::string data(16, 'x');
    for (int i = 0; i < kBurst; ++i) zmq_send(tx, data.data(), data.size(), 0);
    consumer.join();
    total += kBurst;
  }
  zmq_close(tx);
  zmq_close(rx);
  zmq_ctx_term(zctx);
  state.counters["msgs_per_s"] = benchmark::Counter(static_cast<double>(total), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ZeroMQ_Throughput)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);

// ---------------------------------------------------------------------------- fan-out

void BM_Bus_FanOut8(benchmark::State& state) {
  // The cost of handing one message to 8 subscribers must not depend on its
  // size: they all get the same object.
  auto ctx = quiet_context(bus::ClockType::Sim);
  bus::DeterministicExecutor ex(ctx->clock());
  auto src = node(ctx, "src");
  auto pub = src->create_publisher<StringMsg>("t");
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::vector<std::shared_ptr<bus::Subscription<StringMsg>>> subs;
  std::size_t seen = 0;
  for (int i = 0; i < 8; ++i) {
    auto n = node(ctx, "dst" + std::to_string(i));
    subs.push_back(n->create_subscription<StringMsg>("t", bus::QoS::keep_last(2),
                                                     [&](const StringMsg& m) { seen += m.data.size(); }));
    ex.add_node(n);
    nodes.push_back(n);
  }
  auto msg = std::shared_ptr<const StringMsg>(payload(static_cast<std::size_t>(state.range(0))));
  for (auto _ : state) {
    pub->publish(msg);  // re-publishing one object: measures delivery, not allocation
    ex.spin_until_idle();
  }
  benchmark::DoNotOptimize(seen);
}
BENCHMARK(BM_Bus_FanOut8)->Arg(64)->Arg(1 << 20);

void BM_Reference_Copy8(benchmark::State& state) {
  // What a copying middleware pays at least: one copy per subscriber.
  const std::string src(static_cast<std::size_t>(state.range(0)), 'x');
  std::vector<std::string> dst(8);
  for (auto _ : state) {
    for (auto& d : dst) d = src;
    benchmark::DoNotOptimize(dst.data());
  }
}
BENCHMARK(BM_Reference_Copy8)->Arg(64)->Arg(1 << 20);

}  // namespace

BENCHMARK_MAIN();
