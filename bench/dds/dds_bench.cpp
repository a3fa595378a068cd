// SPDX-License-Identifier: Apache-2.0
// The graph across processes over DDS beside Cyclone DDS alone and beside the
// same graph in one process, in one run (pingpong.hpp says what runs where).
//
//   round trip:  one message in flight; p50/p99 of the round trip as counters
//                (stamped from the publish to the ping side's callback).
//   stream:      up to 64 messages in flight: messages per second through
//                the round trip, and payload bytes per second each way.
//
//   InProcess            the relay in this process (zero copy);
//   InProcessWithBridge  the same with a bridge present and the topics
//                        selected but no remote reader: what DDS costs a
//                        process nobody outside listens to;
//   Dds                  the relay in a second process, both bridges between;
//   Engine               Cyclone alone with the same sertype, QoS and
//                        configuration, relaying on its receive thread (the
//                        reference: what DDS itself costs).
//
// bench/dds/side_by_side.py runs Engine and Dds (and Cyclone's ddsperf) and
// prints the table of docs/benchmarks.md.
//
//   dds_bench --idle-cpu SECONDS   instead: the CPU both processes of each
//                                  cross-process case use while nothing is
//                                  sent for SECONDS (after 1000 round trips).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <fstream>

#include "pingpong.hpp"

using namespace tinyline;
using namespace tinyline::bench_dds;

namespace {

/// Publishes one ping per iteration and records each round trip; `ping()`
/// sends, `p.arrivals` counts the pongs.
template <class P, class Ping>
void round_trip(benchmark::State& state, P& p, Ping&& ping) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  std::vector<double> rtt_us;
  std::uint64_t sent = p.arrivals.count.load();
  for (auto _ : state) {
    const std::int64_t t0 = now_ns();
    ping();
    p.arrivals.wait_for(++sent);
    rtt_us.push_back(static_cast<double>(p.arrivals.last_ns.load() - t0) * 1e-3);
  }
  std::sort(rtt_us.begin(), rtt_us.end());
  state.counters["p50_us"] = rtt_us[rtt_us.size() / 2];
  state.counters["p99_us"] = rtt_us[rtt_us.size() * 99 / 100];
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

/// Up to kWindow pings in flight; every one makes the round trip.
template <class P, class Ping>
void stream(benchmark::State& state, P& p, Ping&& ping) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  const std::uint64_t base = p.arrivals.count.load();
  std::uint64_t sent = 0;
  for (auto _ : state) {
    if (sent >= kWindow) p.arrivals.wait_for(base + sent - kWindow + 1);
    ping();
    ++sent;
  }
  p.arrivals.wait_for(base + sent);
  state.SetItemsProcessed(static_cast<std::int64_t>(sent));
  state.SetBytesProcessed(static_cast<std::int64_t>(sent * bytes));
}

void tinyline_case(benchmark::State& state, Pinger& p, bool streaming) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  // A publisher makes a new message each time; making it is not DDS's cost.
  std::unique_ptr<Cloud> next = cloud(bytes);
  auto ping = [&] {
    p.pub->publish(std::move(next));
    state.PauseTiming();
    next = cloud(bytes);
    state.ResumeTiming();
  };
  auto ping_streaming = [&] { p.pub->publish(cloud(bytes)); };
  if (streaming) {
    stream(state, p, ping_streaming);
  } else {
    round_trip(state, p, ping);
  }
}

void local_case(benchmark::State& state, Mode mode, bool streaming) {
  Pinger p(mode);
  tinyline_case(state, p, streaming);
}

void engine_case(benchmark::State& state, bool streaming) {
  EnginePinger& p = Sessions::get().engine();
  p.set_payload(static_cast<std::size_t>(state.range(0)));
  auto ping = [&] { p.ping(); };
  if (streaming) {
    stream(state, p, ping);
  } else {
    round_trip(state, p, ping);
  }
}

void BM_InProcess_RoundTrip(benchmark::State& s) { local_case(s, Mode::InProcess, false); }
void BM_InProcessWithBridge_RoundTrip(benchmark::State& s) { local_case(s, Mode::InProcessWithBridge, false); }
void BM_Engine_RoundTrip(benchmark::State& s) { engine_case(s, false); }
void BM_Dds_RoundTrip(benchmark::State& s) { tinyline_case(s, Sessions::get().tinyline(), false); }
void BM_InProcess_Stream(benchmark::State& s) { local_case(s, Mode::InProcess, true); }
void BM_Engine_Stream(benchmark::State& s) { engine_case(s, true); }
void BM_Dds_Stream(benchmark::State& s) { tinyline_case(s, Sessions::get().tinyline(), true); }

void sizes(benchmark::internal::Benchmark* b) {
  for (long n : {64L, 2048L, 65536L, 1L << 20}) b->Arg(n);
  b->UseRealTime()->Unit(benchmark::kMicrosecond)->MinTime(1.0);
}

/// One VGA XYZRGB cloud (640 x 480 points of 32 bytes, about 10 MB): round
/// trips only (64 in flight would need 1.3 GB of chunks).
constexpr long kVgaCloud = 640L * 480L * 32L;
void round_trip_sizes(benchmark::internal::Benchmark* b) {
  sizes(b);
  b->Arg(kVgaCloud);
}

BENCHMARK(BM_InProcess_RoundTrip)->Apply(round_trip_sizes);
BENCHMARK(BM_InProcessWithBridge_RoundTrip)->Apply(round_trip_sizes);
BENCHMARK(BM_Engine_RoundTrip)->Apply(round_trip_sizes);
BENCHMARK(BM_Dds_RoundTrip)->Apply(round_trip_sizes);
BENCHMARK(BM_InProcess_Stream)->Apply(sizes);
BENCHMARK(BM_Engine_Stream)->Apply(sizes);
BENCHMARK(BM_Dds_Stream)->Apply(sizes);

/// CPU seconds process `pid`'s threads have run so far: the sum of
/// /proc/<pid>/task/*/schedstat's first field (ns on a core; finer than the
/// 10 ms ticks of /proc/<pid>/stat).
double cpu_seconds(pid_t pid) {
  double ns = 0;
  const std::filesystem::path tasks = fmt::format("/proc/{}/task", pid);
  for (const auto& t : std::filesystem::directory_iterator(tasks)) {
    std::ifstream in(t.path() / "schedstat");
    double on_cpu = 0;
    if (in >> on_cpu) ns += on_cpu;
  }
  return ns * 1e-9;
}

/// Warms one cross-process case up, then prints the CPU share of both of its
/// processes while nothing is sent for `seconds`.
template <class P, class Ping>
void idle_cpu(const char* what, P& p, Ping&& ping, int seconds) {
  for (std::uint64_t k = 0; k < 1000; ++k) {
    const std::uint64_t n = p.arrivals.count.load() + 1;
    ping();
    p.arrivals.wait_for(n);
  }
  const pid_t pong = Sessions::get().pong_pid();
  const double self0 = cpu_seconds(getpid()), pong0 = cpu_seconds(pong);
  std::this_thread::sleep_for(std::chrono::seconds(seconds));
  const double self1 = cpu_seconds(getpid()), pong1 = cpu_seconds(pong);
  std::printf("%s, idle %d s: ping process %.2f%% of a core (%.1f ms), pong process %.2f%% (%.1f ms)\n", what, seconds,
              100 * (self1 - self0) / seconds, 1e3 * (self1 - self0), 100 * (pong1 - pong0) / seconds,
              1e3 * (pong1 - pong0));
}

int idle_cpu_main(int seconds) {
  EnginePinger& e = Sessions::get().engine();
  e.set_payload(64);
  idle_cpu(
      "Cyclone alone", e, [&] { e.ping(); }, seconds);
  Pinger& t = Sessions::get().tinyline();
  idle_cpu(
      "tinyline", t, [&] { t.pub->publish(cloud(64)); }, seconds);
  Sessions::get().close();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (const int rc = maybe_pong_main(argc, argv); rc >= 0) return rc;
  if (argc > 1 && std::string(argv[1]) == "--print-config") {  // for ddsperf beside it (side_by_side.py)
    std::puts(settings("ping").effective_config().c_str());
    return 0;
  }
  if (argc > 2 && std::string(argv[1]) == "--idle-cpu") return idle_cpu_main(std::stoi(argv[2]));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  Sessions::get().close();
  benchmark::Shutdown();
  return 0;
}
