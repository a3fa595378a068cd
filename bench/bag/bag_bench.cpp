// SPDX-License-Identifier: Apache-2.0
// Bag benchmarks (docs/benchmarks.md, "Bags"), each beside its reference in
// the same run:
//   Record/*          the MCAP writer with none, lz4, zstd on 2 s of realistic
//                     traffic, into a file   vs  RawWrite: write(2) of the same
//                     message bytes through the same 1 MiB buffering (the floor)
//   RecordAsync/0|16  the recorder's path: serialized messages handed to the
//                     AsyncWriter thread, timed until the file is closed; as
//                     one burst (0), or sustained with <= 16 MB queued
//                     vs  CopyOnly: the copy of every message that path makes
//   IndexedRead       one topic of five (/tiny/scan) through the summary
//                     vs  LinearRead: the same topic by reading every record
//   Replay/laser      the laser topics through a subscriber node with the
//                     replay helper (sim time, deterministic executor)
//                     vs  DecodeOnly: reading and decoding the same messages
//                     with no bus; both report x real time (bag s / wall s)
//   Player/laser      the player node at full speed into a subscriber on
//                     another thread, x real time
// Files go to $TMPDIR (default /tmp); page cache for every variant alike.
#include <benchmark/benchmark.h>

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <thread>

#include <tinyline/bag/async_writer.hpp>
#include <tinyline/bag/crc32.hpp>
#include <tinyline/bag/player.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/replay.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bus/executor.hpp>

#include "traffic.hpp"

namespace {

using namespace tinyline;

// The machine is shared: the least disturbed repetition is the best estimate
// of what the code costs, so every benchmark also reports the minimum.
double min_of(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

// Minor page faults of the process so far: fresh memory the kernel had to map and zero.
long minor_faults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}
using tinyline::bench::TrafficMessage;

std::string tmp_path(const std::string& name) {
  const char* d = std::getenv("TMPDIR");
  return (std::filesystem::path(d ? d : "/tmp") / ("tinyline_bag_bench_" + name)).string();
}

const std::vector<TrafficMessage>& record_traffic() {
  static const auto t = tinyline::bench::make_traffic(2.0, /*with_cloud=*/true);
  return t;
}

std::uint64_t payload_bytes(const std::vector<TrafficMessage>& t) {
  std::uint64_t n = 0;
  for (const auto& m : t) n += m.cdr.size();
  return n;
}

// The floor: the same message bytes through write(2) with the writer's 1 MiB buffering.
void BM_RawWrite(benchmark::State& state) {
  const auto& traffic = record_traffic();
  const std::string path = tmp_path("raw.bin");
  std::vector<std::uint8_t> buf;
  buf.reserve(1 << 20);
  for (auto _ : state) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    auto flush = [&] {
      std::size_t off = 0;
      while (off < buf.size()) {
        const ssize_t w = ::write(fd, buf.data() + off, buf.size() - off);
        if (w <= 0) std::abort();
        off += static_cast<std::size_t>(w);
      }
      buf.clear();
    };
    for (const auto& m : traffic) {
      if (buf.size() + m.cdr.size() > (1 << 20)) flush();
      if (m.cdr.size() >= (1 << 20)) {
        std::size_t off = 0;
        while (off < m.cdr.size()) {
          const ssize_t w = ::write(fd, m.cdr.data() + off, m.cdr.size() - off);
          if (w <= 0) std::abort();
          off += static_cast<std::size_t>(w);
        }
      } else {
        buf.insert(buf.end(), m.cdr.begin(), m.cdr.end());
      }
    }
    flush();
    ::close(fd);
  }
  std::filesystem::remove(path);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * payload_bytes(traffic)));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * traffic.size()));
}
BENCHMARK(BM_RawWrite)->Unit(benchmark::kMillisecond)->UseRealTime()->ComputeStatistics("min", min_of);

void BM_Record(benchmark::State& state) {
  const auto comp = static_cast<bag::Compression>(state.range(0));
  const int level = static_cast<int>(state.range(1));
  const auto& traffic = record_traffic();
  const std::string path = tmp_path("record.mcap");
  std::uint64_t file_bytes = 0;
  const long faults0 = minor_faults();
  for (auto _ : state) {
    bag::ros2::Ros2Writer w;
    bag::WriterOptions o;
    o.compression = comp;
    o.compression_level = level;
    if (!w.open(path, o).ok()) std::abort();
    bag::ChannelId ids[5];
    for (int k = 0; k < 5; ++k) {
      if (!w.add_topic(bench::kTopics[k].name, bench::kTopics[k].type(), ids[k]).ok()) std::abort();
    }
    for (const auto& m : traffic) {
      const auto t = static_cast<bag::Timestamp>(m.t_ns);
      if (!w.write_serialized(ids[m.topic], m.cdr, t, t).ok()) std::abort();
    }
    if (!w.close().ok()) std::abort();
    file_bytes = w.writer().stats().file_bytes;
  }
  std::filesystem::remove(path);
  const auto payload = payload_bytes(traffic);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * payload));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * traffic.size()));
  state.counters["file_MB"] = static_cast<double>(file_bytes) / 1e6;
  state.counters["ratio"] = static_cast<double>(payload) / static_cast<double>(file_bytes);
  state.counters["faults"] = static_cast<double>(minor_faults() - faults0) / static_cast<double>(state.iterations());
  state.SetLabel(std::string(bag::to_string(comp)) + (level != 0 ? "-" + std::to_string(level) : std::string()));
}
BENCHMARK(BM_Record)
    ->Args({static_cast<int>(bag::Compression::None), 0})
    ->Args({static_cast<int>(bag::Compression::Lz4), 0})
    ->Args({static_cast<int>(bag::Compression::Zstd), 1})
    ->Args({static_cast<int>(bag::Compression::Zstd), 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->ComputeStatistics("min", min_of);

// The recorder's path: the caller only queues; compression and I/O on the writer thread.
// First arg 0: the 2 s of traffic handed over as one burst (every copy alive at
// once); N: sustained, the caller waiting while N MB are queued, as traffic
// arriving no faster than the writer drains it keeps the queue short.
// Second arg: 1 the copies go into buffers recycled by the writer thread (as
// the recorder does), 0 every copy is a fresh allocation (the reference).
void BM_RecordAsync(benchmark::State& state) {
  const auto& traffic = record_traffic();
  const std::string path = tmp_path("async.mcap");
  const std::uint64_t max_queued = static_cast<std::uint64_t>(state.range(0)) << 20;
  const bool recycle = state.range(1) != 0;
  std::uint64_t dropped = 0;
  std::uint64_t high_water = 0;
  const long faults0 = minor_faults();
  for (auto _ : state) {
    bag::AsyncWriter w;
    bag::AsyncWriterOptions o;
    o.writer.compression = bag::Compression::Lz4;
    o.max_queue_bytes = 1ULL << 31;  // measure throughput, not the budget
    if (!recycle) o.recycle_per_topic = 0;
    if (!w.open(path, o).ok()) std::abort();
    bag::AsyncWriter::TopicId ids[5];
    for (int k = 0; k < 5; ++k) ids[k] = w.add_topic(bench::kTopics[k].name, bench::kTopics[k].type());
    for (const auto& m : traffic) {
      while (max_queued > 0 && w.stats().queued_bytes > max_queued) {
        std::this_thread::sleep_for(std::chrono::microseconds(100));  // not spinning: CPU is measured
      }
      const auto t = static_cast<bag::Timestamp>(m.t_ns);
      auto copy = w.take_buffer(ids[m.topic]);  // as the recorder serializes into a recycled buffer
      copy.assign(m.cdr.begin(), m.cdr.end());
      (void)w.push(ids[m.topic], std::move(copy), t, t, 0);
    }
    high_water = std::max(high_water, w.stats().max_queued_bytes);
    if (!w.close().ok()) std::abort();
    dropped += w.stats().dropped;
  }
  std::filesystem::remove(path);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * payload_bytes(traffic)));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * traffic.size()));
  state.counters["dropped"] = static_cast<double>(dropped);
  state.counters["faults"] = static_cast<double>(minor_faults() - faults0) / static_cast<double>(state.iterations());
  state.counters["queued_MB"] = static_cast<double>(high_water) / 1e6;
  state.SetLabel(std::string(max_queued > 0 ? "lz4, sustained" : "lz4, one burst") +
                 (recycle ? ", recycled buffers" : ", fresh buffers"));
}
// The part of RecordAsync that is not the writer's: a fresh copy of every message's
// bytes, as the recorder's serialization makes one, freed when written.
void BM_CopyOnly(benchmark::State& state) {
  const auto& traffic = record_traffic();
  for (auto _ : state) {
    for (const auto& m : traffic) {
      std::vector<std::uint8_t> copy(m.cdr);
      benchmark::DoNotOptimize(copy.data());
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * payload_bytes(traffic)));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * traffic.size()));
}
BENCHMARK(BM_CopyOnly)->Unit(benchmark::kMillisecond)->UseRealTime()->ComputeStatistics("min", min_of);

// CPU of the whole process: the writer thread does the compression and I/O.
BENCHMARK(BM_RecordAsync)
    ->Args({0, 1})
    ->Args({16, 1})
    ->Args({16, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->ComputeStatistics("min", min_of);

// CRC-32 of a chunk: the carry-less-multiply path against the table-driven one.
void BM_Crc32(benchmark::State& state) {
  std::vector<std::uint8_t> data(1 << 20);
  std::mt19937 rng(1);
  for (auto& b : data) b = static_cast<std::uint8_t>(rng());
  const bool fast = state.range(0) != 0;
  std::uint32_t c = 0;
  for (auto _ : state) c ^= fast ? bag::crc32(data) : bag::crc32_portable(data);
  benchmark::DoNotOptimize(c);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * data.size()));
  state.SetLabel(fast ? "pclmul" : "tables");
}
BENCHMARK(BM_Crc32)->Arg(1)->Arg(0)->ComputeStatistics("min", min_of);

// ---------------------------------------------------------------------------- reading

// 10 s of all five topics, lz4, written once.
constexpr double kReadSeconds = 10.0;

// Writes `seconds` of the realistic traffic on the first `n_topics` topics of
// bench::kTopics to a bag in the temporary directory.
std::string write_traffic_bag(const char* name, double seconds, bool with_cloud, bool with_extra, int n_topics) {
  const std::string p = tmp_path(name);
  const auto traffic = tinyline::bench::make_traffic(seconds, with_cloud, with_extra);
  bag::ros2::Ros2Writer w;
  if (!w.open(p, bag::WriterOptions{}).ok()) std::abort();
  std::vector<bag::ChannelId> ids(static_cast<std::size_t>(n_topics));
  for (int k = 0; k < n_topics; ++k) {
    if (!w.add_topic(bench::kTopics[k].name, bench::kTopics[k].type(), ids[static_cast<std::size_t>(k)]).ok())
      std::abort();
  }
  for (const auto& m : traffic) {
    const auto t = static_cast<bag::Timestamp>(m.t_ns);
    if (!w.write_serialized(ids[static_cast<std::size_t>(m.topic)], m.cdr, t, t).ok()) std::abort();
  }
  if (!w.close().ok()) std::abort();
  return p;
}

const std::string& read_bag() {
  static const std::string path =
      write_traffic_bag("read.mcap", kReadSeconds, /*with_cloud=*/true, /*with_extra=*/true, 5);
  return path;
}

void read_one_topic(benchmark::State& state, bool ignore_summary) {
  const std::string& path = read_bag();
  std::uint64_t n = 0, bytes = 0;
  for (auto _ : state) {
    bag::Reader r;
    bag::ReaderOptions ro;
    ro.ignore_summary = ignore_summary;
    if (!r.open(path, ro).ok()) std::abort();
    bag::ReadOptions q;
    q.topics = {"/tiny/scan"};
    n = 0;
    if (!r.for_each(q, [&](const bag::MessageView& v) {
            ++n;
            bytes += v.message.data.size();
            return true;
          }).ok())
      std::abort();
    if (n != static_cast<std::uint64_t>(kReadSeconds * 100)) std::abort();  // line scans at 100 Hz
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  state.counters["file_MB"] = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
  state.counters["bag_s_per_s"] =
      benchmark::Counter(kReadSeconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_IndexedRead_OneTopicOfFive(benchmark::State& state) { read_one_topic(state, false); }
void BM_LinearRead_OneTopicOfFive(benchmark::State& state) { read_one_topic(state, true); }
BENCHMARK(BM_IndexedRead_OneTopicOfFive)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->ComputeStatistics("min", min_of);
BENCHMARK(BM_LinearRead_OneTopicOfFive)->Unit(benchmark::kMillisecond)->UseRealTime()->ComputeStatistics("min", min_of);

// ---------------------------------------------------------------------------- replay

// 60 s of the laser topics (raw scans at 36 Hz, line scans at 100 Hz).
constexpr double kLaserSeconds = 60.0;
const std::string& laser_bag() {
  static const std::string path =
      write_traffic_bag("laser.mcap", kLaserSeconds, /*with_cloud=*/false, /*with_extra=*/false, 2);
  return path;
}

// A node that touches every scan (sums its ranges), as a consumer would.
class ScanSink : public bus::Node {
 public:
  explicit ScanSink(bus::NodeOptions o) : Node(std::move(o)) {
    a_ = create_subscription<tinyline_msgs::msg::LineScan>("/tiny/scan", bus::QoS::reliable(1000),
                                                           [this](const tinyline_msgs::msg::LineScan& m) {
                                                             for (float d : m.distance_m) sum_ += d == d ? d : 0.0F;
                                                             received.fetch_add(1, std::memory_order_relaxed);
                                                           });
    b_ = create_subscription<tinyline_msgs::msg::RawScan>("/tiny/raw", bus::QoS::reliable(1000),
                                                          [this](const tinyline_msgs::msg::RawScan& m) {
                                                            sum_ += static_cast<float>(m.a.size());
                                                            received.fetch_add(1, std::memory_order_relaxed);
                                                          });
  }
  std::atomic<std::uint64_t> received{0};
  float sum_ = 0;

 private:
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> a_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::RawScan>> b_;
};

void BM_Replay_Laser(benchmark::State& state) {
  const std::string& path = laser_bag();
  std::uint64_t n = 0;
  for (auto _ : state) {
    bag::Replay replay(path);
    auto sink = replay.add<ScanSink>("sink");
    const auto out = replay.run();
    if (!out.status.ok() || sink->received.load() != out.replayed) std::abort();
    n = out.replayed;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  state.counters["x_realtime"] =
      benchmark::Counter(kLaserSeconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Replay_Laser)->Unit(benchmark::kMillisecond)->UseRealTime()->ComputeStatistics("min", min_of);

void BM_DecodeOnly_Laser(benchmark::State& state) {
  const std::string& path = laser_bag();
  std::uint64_t n = 0;
  float sum = 0;
  for (auto _ : state) {
    bag::Reader r;
    if (!r.open(path).ok()) std::abort();
    n = 0;
    (void)r.for_each({}, [&](const bag::MessageView& v) {
      auto m = bag::ros2::type_support_for(v.schema, *v.channel)->deserialize(v.message.data);
      sum += static_cast<float>(reinterpret_cast<std::uintptr_t>(m.get()) & 1);
      ++n;
      return true;
    });
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  state.counters["x_realtime"] =
      benchmark::Counter(kLaserSeconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DecodeOnly_Laser)->Unit(benchmark::kMillisecond)->UseRealTime()->ComputeStatistics("min", min_of);

void BM_Player_Laser(benchmark::State& state) {
  const std::string& path = laser_bag();
  std::uint64_t n = 0;
  for (auto _ : state) {
    auto ctx = bus::Context::create();
    bus::SingleThreadedExecutor exec(ctx->clock());
    bus::NodeOptions so;
    so.name = "sink";
    so.context = ctx;
    auto sink = std::make_shared<ScanSink>(so);
    bag::PlayerOptions po;
    po.path = path;
    po.rate = 0;  // as fast as the bus takes it
    bus::NodeOptions no;
    no.name = "player";
    no.context = ctx;
    auto player = std::make_shared<bag::Player>(no, po);
    exec.add_node(sink);
    exec.add_node(player);
    std::thread spin([&] { exec.spin(); });
    if (!player->wait_finished(std::chrono::minutes(5))) std::abort();
    n = player->stats().published;
    // Done when the subscriber has taken every message.
    while (sink->received.load() < n) std::this_thread::yield();
    exec.stop();
    spin.join();
    player->stop();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  state.counters["x_realtime"] =
      benchmark::Counter(kLaserSeconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
// CPU of the whole process: playback, the executor and the subscriber run on their own threads.
BENCHMARK(BM_Player_Laser)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->ComputeStatistics("min", min_of);

}  // namespace

BENCHMARK_MAIN();
