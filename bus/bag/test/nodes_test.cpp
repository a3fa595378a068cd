// SPDX-License-Identifier: Apache-2.0
// The recorder, the player and the replay helper on the bus. Time is stepped
// (sim clock, deterministic executor) or waited for on conditions; nothing
// sleeps.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <tinyline/bag/async_writer.hpp>
#include <tinyline/bag/player.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/register.hpp>
#include <tinyline/bag/replay.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>
#include <tinyline/msg/rosgraph_msgs/clock.hpp>
#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

namespace tinyline::bag {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path out_dir() {
  const fs::path d = fs::path(TINYLINE_BINARY_DIR) / "bag_nodes";
  fs::create_directories(d);
  return d;
}

std::shared_ptr<bus::Context> sim_context(std::shared_ptr<bus::LogSink> sink = nullptr) {
  return bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, std::move(sink)});
}

bus::NodeOptions opts(const std::shared_ptr<bus::Context>& ctx, std::string name) {
  bus::NodeOptions o;
  o.name = std::move(name);
  o.context = ctx;
  return o;
}

std::unique_ptr<tinyline_msgs::msg::LineScan> line_scan(std::uint32_t i) {
  auto m = std::make_unique<tinyline_msgs::msg::LineScan>();
  m->set_index = i;
  m->angles.assign(256, 0.25F);
  m->distance_m.assign(256, 0.5F + 0.001F * static_cast<float>(i % 100));
  m->intensity.assign(256, 10.0F);
  m->reflectance.assign(256, 1000.0F);
  m->pulses.assign(256, 40);
  m->status.assign(256, 0);
  return m;
}

std::unique_ptr<tinyline_msgs::msg::RawScan> raw_scan(std::uint32_t i) {
  auto m = std::make_unique<tinyline_msgs::msg::RawScan>();
  m->set_index = i;
  m->pixels = 272;
  m->pulses = {10, 40, 160, 640, 2560};
  m->a.assign(5 * 272, static_cast<std::int16_t>(i));
  m->b.assign(5 * 272, 7);
  return m;
}

// Publishes line scans and raw scans from timers (the sensor at `factor` times its rate).
class Sensor : public bus::Node {
 public:
  Sensor(bus::NodeOptions o, double factor) : Node(std::move(o)) {
    scans_ = create_publisher<tinyline_msgs::msg::LineScan>("/tiny/scan");
    raws_ = create_publisher<tinyline_msgs::msg::RawScan>("/tiny/raw");
    timers_.push_back(create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / (100.0 * factor))),
                                   [this] { scans_->publish(line_scan(n_scan_++)); }));
    timers_.push_back(create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / (36.0 * factor))),
                                   [this] { raws_->publish(raw_scan(n_raw_++)); }));
  }
  std::uint32_t n_scan_ = 0, n_raw_ = 0;

 private:
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LineScan>> scans_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::RawScan>> raws_;
  std::vector<std::shared_ptr<bus::Timer>> timers_;
};

struct TopicCounts {
  std::map<std::string, std::vector<std::uint32_t>> sequences;
  std::map<std::string, std::vector<Timestamp>> times;
  std::uint64_t total = 0;
};

TopicCounts read_counts(const std::string& path, Status* status = nullptr) {
  TopicCounts c;
  Reader r;
  const Status s = r.open(path);
  EXPECT_TRUE(s.ok()) << s.str();
  const Status rs = r.for_each({}, [&](const MessageView& v) {
    c.sequences[v.channel->topic].push_back(v.message.sequence);
    c.times[v.channel->topic].push_back(v.message.log_time);
    ++c.total;
    return true;
  });
  if (status) *status = rs;
  return c;
}

// ---------------------------------------------------------------------------- recorder

TEST(Recorder, ABurstAtTenTimesTheSensorRateFor10sIsRecordedCompletely) {
  auto ctx = sim_context();
  bus::DeterministicExecutor exec(ctx->clock());
  RecorderOptions ro;
  ro.path = (out_dir() / "burst.mcap").string();
  auto recorder = std::make_shared<Recorder>(opts(ctx, "recorder"), ro);
  auto sensor = std::make_shared<Sensor>(opts(ctx, "sensor"), 10.0);
  exec.add_node(recorder);
  exec.add_node(sensor);
  const bus::Time t0 = bus::Time::from_seconds(1.0);
  exec.advance_to(t0);                             // sim time starts; timers count from here
  exec.advance_to(t0 + std::chrono::seconds(10));  // 10 s at 1000 Hz + 360 Hz
  ASSERT_EQ(sensor->n_scan_, 10000U);
  ASSERT_EQ(sensor->n_raw_, 3600U);
  ASSERT_TRUE(recorder->stop().ok());
  const RecorderStats st = recorder->stats();
  EXPECT_EQ(st.dropped, 0U);
  EXPECT_EQ(st.written, 13600U);
  EXPECT_EQ(st.subscription_timeouts, 0U);

  Status s;
  const TopicCounts c = read_counts(ro.path, &s);
  ASSERT_TRUE(s.ok()) << s.str();
  ASSERT_EQ(c.sequences.at("/tiny/scan").size(), 10000U);
  ASSERT_EQ(c.sequences.at("/tiny/raw").size(), 3600U);
  // Every message, in order, with its publish sequence and its sim time of arrival.
  for (std::uint32_t i = 0; i < 10000; ++i) {
    ASSERT_EQ(c.sequences.at("/tiny/scan")[i], i + 1);
    ASSERT_EQ(c.times.at("/tiny/scan")[i], static_cast<Timestamp>(t0.ns + (i + 1) * 1'000'000LL));
  }
  Reader r;
  ASSERT_TRUE(r.open(ro.path).ok());
  EXPECT_TRUE(r.verify().ok());
  ASSERT_EQ(r.summary().metadata_indexes.size(), 1U);
  Metadata md;
  ASSERT_TRUE(r.read_metadata(r.summary().metadata_indexes[0], md).ok());
  EXPECT_EQ(md.name, "tinyline_recorder");
  EXPECT_EQ(md.metadata.at("dropped"), "0");
  EXPECT_EQ(md.metadata.at("written"), "13600");
}

// A sink whose writes block while the gate is closed: a disk that stalls.
class GateWritable : public Writable {
 public:
  Status write(std::span<const std::uint8_t> b) override {
    std::unique_lock lk(mu_);
    cv_.wait(lk, [&] { return open_; });
    return mem_.write(b);
  }
  Status flush() override { return {}; }
  Status close() override { return {}; }
  std::uint64_t size() const override { return mem_.size(); }
  const std::string& name() const override { return mem_.name(); }
  void set_open(bool open) {
    {
      std::lock_guard lk(mu_);
      open_ = open;
    }
    cv_.notify_all();
  }
  std::vector<std::uint8_t> data() const { return mem_.data(); }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool open_ = true;
  MemoryWritable mem_;
};

TEST(Recorder, AQueueThatWouldOverflowIsReportedNeverASilentLoss) {
  auto log = std::make_shared<bus::CaptureSink>();
  auto ctx = sim_context(log);
  bus::DeterministicExecutor exec(ctx->clock());
  auto sink = std::make_unique<GateWritable>();
  GateWritable* gate = sink.get();
  RecorderOptions ro;
  ro.writer.max_queue_bytes = 1 << 20;
  ro.writer.writer.chunk_size_bytes = 4096;
  ro.writer.flush_interval_s = 0;
  auto recorder = std::make_shared<Recorder>(opts(ctx, "recorder"), ro, std::move(sink));
  auto pub_node = std::make_shared<bus::Node>(opts(ctx, "sensor"));
  auto pub = pub_node->create_publisher<tinyline_msgs::msg::LineScan>("/tiny/scan");
  exec.add_node(recorder);
  exec.add_node(pub_node);
  exec.advance_to(bus::Time::from_seconds(1));
  gate->set_open(false);                // the disk stalls
  constexpr std::uint32_t kSent = 600;  // ~6 KB each: 3.6 MB against a 1 MiB queue
  for (std::uint32_t i = 0; i < kSent; ++i) {
    EXPECT_TRUE(pub->publish(line_scan(i)).ok());  // the publisher is never refused or blocked
    exec.spin_until_idle();
  }
  gate->set_open(true);
  ASSERT_TRUE(recorder->stop().ok());
  const RecorderStats st = recorder->stats();
  EXPECT_GT(st.dropped, 0U);
  EXPECT_EQ(st.written + st.dropped, kSent);
  EXPECT_TRUE(log->contains(bus::LogLevel::Error, "dropped a message on /tiny/scan"));
  EXPECT_TRUE(log->contains(bus::LogLevel::Error, "the write queue is full"));

  // The file holds exactly the messages reported written and says how many were dropped.
  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(gate->data())).ok());
  std::uint64_t n = 0;
  std::uint32_t last = 0;
  ASSERT_TRUE(r.for_each({}, [&](const MessageView& v) {
                 EXPECT_GT(v.message.sequence, last);
                 last = v.message.sequence;
                 ++n;
                 return true;
               }).ok());
  EXPECT_EQ(n, st.written);
  Metadata md;
  ASSERT_TRUE(r.read_metadata(r.summary().metadata_indexes.at(0), md).ok());
  EXPECT_EQ(md.metadata.at("dropped"), std::to_string(st.dropped));
  EXPECT_EQ(md.metadata.at("dropped_by_topic"), "/tiny/scan: " + std::to_string(st.dropped));
}

// A launch stops its executor first and its nodes after: what the recorder's
// queues hold then was published before the end and belongs in the file (a
// loaded machine leaves a message or two there; `--until` leaves the very
// message it waited for).
TEST(Recorder, RecordsWhatItsQueuesHoldWhenStoppedAfterItsExecutor) {
  auto ctx = bus::Context::create(bus::ContextOptions{bus::ClockType::Wall, nullptr});
  bus::MultiThreadedExecutor exec(ctx->clock(), 2);
  auto sink = std::make_unique<MemoryWritable>();
  auto recorder = std::make_shared<Recorder>(opts(ctx, "recorder"), RecorderOptions{}, std::move(sink));
  auto pub_node = std::make_shared<bus::Node>(opts(ctx, "sensor"));
  auto pub = pub_node->create_publisher<tinyline_msgs::msg::LineScan>("/tiny/scan");
  exec.add_node(recorder);
  exec.add_node(pub_node);
  recorder->start();
  constexpr std::uint32_t kSent = 10;
  for (std::uint32_t i = 0; i < kSent; ++i) ASSERT_TRUE(pub->publish(line_scan(i)).ok());
  exec.stop();  // as tinyline launch does, before the nodes' on_stop()
  ASSERT_TRUE(recorder->stop().ok());
  const RecorderStats st = recorder->stats();
  EXPECT_EQ(st.written, kSent);
  EXPECT_EQ(st.dropped, 0U);
}

TEST(Recorder, RecordsChosenTopicsIncludingOnesCreatedLaterWithTheirQos) {
  auto ctx = sim_context();
  bus::DeterministicExecutor exec(ctx->clock());
  const std::string path = (out_dir() / "chosen.mcap").string();
  auto recorder = std::make_shared<Recorder>(
      opts(ctx, "recorder").param("path", path).param("topics", std::vector<std::string>{"/a", "/late"}));
  exec.add_node(recorder);
  exec.advance_to(bus::Time::from_seconds(1));  // recording starts before any topic exists
  auto n = std::make_shared<bus::Node>(opts(ctx, "talker"));
  exec.add_node(n);
  auto a = n->create_publisher<std_msgs::msg::String>("/a", bus::QoS::keep_last(3).latched());
  auto b = n->create_publisher<std_msgs::msg::String>("/b");
  for (int i = 0; i < 5; ++i) {
    a->publish(std::make_unique<std_msgs::msg::String>());
    b->publish(std::make_unique<std_msgs::msg::String>());
    exec.spin_until_idle();
  }
  auto late = n->create_publisher<std_msgs::msg::String>("/late");
  late->publish(std::make_unique<std_msgs::msg::String>());
  exec.spin_until_idle();
  ASSERT_TRUE(recorder->stop().ok());
  const TopicCounts c = read_counts(path);
  EXPECT_EQ(c.sequences.count("/b"), 0U);
  EXPECT_EQ(c.sequences.at("/a").size(), 5U);
  EXPECT_EQ(c.sequences.at("/late").size(), 1U);
  Reader r;
  ASSERT_TRUE(r.open(path).ok());
  for (const auto& [id, ch] : r.channels()) {
    if (ch.topic != "/a") continue;
    const std::string& qos = ch.metadata.at("offered_qos_profiles");
    EXPECT_NE(qos.find("depth: 3"), std::string::npos) << qos;
    EXPECT_NE(qos.find("durability: 1"), std::string::npos) << qos;  // transient local
  }
}

TEST(Recorder, IsRegisteredForLaunchFilesAndChecksItsParameters) {
  bus::NodeRegistry reg;
  register_nodes(reg);
  ASSERT_NE(reg.find("bag", "recorder"), nullptr);
  ASSERT_NE(reg.find("bag", "player"), nullptr);
  auto ctx = sim_context();
  EXPECT_THROW(reg.create("bag", "recorder", opts(ctx, "r").param("compression", std::string("gzip"))),
               bus::ParamError);
  EXPECT_THROW(reg.create("bag", "recorder", opts(ctx, "r2").param("bogus", std::int64_t{1})), bus::ParamError);
  EXPECT_THROW(reg.create("bag", "player", opts(ctx, "p")), bus::ParamError);  // path is required
  auto rec = reg.create("bag", "recorder", opts(ctx, "r3").param("compression", std::string("zstd")));
  EXPECT_NE(rec, nullptr);
}

TEST(Recorder, TakesItsSettingsFromItsParameterTableInTheTablesUnits) {
  auto ctx = sim_context();
  Recorder rec(opts(ctx, "r")
                   .param("chunk_size_kb", std::int64_t{2})
                   .param("max_queue_mb", std::int64_t{3})
                   .param("queue_depth", std::int64_t{7})
                   .param("compression", std::string("none"))
                   .param("flush_interval_s", 0.25)
                   .param("topics", std::vector<std::string>{"demo/raw"}));
  const RecorderOptions& o = rec.options();
  EXPECT_EQ(o.writer.writer.chunk_size_bytes, 2u * 1024u);  // set in KiB, held in bytes
  EXPECT_EQ(o.writer.max_queue_bytes, 3u << 20);            // set in MiB
  EXPECT_EQ(o.queue_depth, 7u);
  EXPECT_EQ(o.writer.writer.compression, Compression::None);
  EXPECT_DOUBLE_EQ(o.writer.flush_interval_s, 0.25);
  EXPECT_EQ(o.topics, std::vector<std::string>{"/demo/raw"});  // resolved after the table
  std::map<std::string, std::string> units;
  for (const auto& d : rec.parameters()) units[d.name] = d.constraints.unit;
  EXPECT_EQ(units["chunk_size_kb"], "KiB");
  EXPECT_EQ(units["max_queue_mb"], "MiB");
  EXPECT_EQ(units["flush_interval_s"], "s");
  EXPECT_THROW(Recorder(opts(ctx, "r2").param("chunk_size_kb", std::int64_t{0})), bus::ParamError);
}

TEST(Recorder, KilledWithSigkillMidFileThenRecovered) {
  const fs::path path = out_dir() / "killed_recorder.mcap";
  const fs::path part = out_dir() / "killed_recorder.mcap.part";  // where a recording is until it finishes
  const fs::path fixed = out_dir() / "killed_recorder_recovered.mcap";
  fs::remove(path);
  fs::remove(part);
  int pipefd[2];
  ASSERT_EQ(::pipe(pipefd), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The recording process: a sensor at 10x rate on sim time, stepped forever.
    ::close(pipefd[0]);
    auto ctx = sim_context();
    bus::DeterministicExecutor exec(ctx->clock());
    RecorderOptions ro;
    ro.path = path.string();
    ro.writer.writer.chunk_size_bytes = 64 * 1024;
    ro.writer.on_chunk = [fd = pipefd[1]](const WriterStats& s) {
      const std::uint64_t n = s.chunks;
      if (::write(fd, &n, sizeof(n)) != static_cast<ssize_t>(sizeof(n))) ::_exit(4);
    };
    auto recorder = std::make_shared<Recorder>(opts(ctx, "recorder"), ro);
    auto sensor = std::make_shared<Sensor>(opts(ctx, "sensor"), 10.0);
    exec.add_node(recorder);
    exec.add_node(sensor);
    bus::Time t = bus::Time::from_seconds(1);
    for (;;) {
      exec.advance_to(t);
      t += std::chrono::milliseconds(10);
    }
  }
  ::close(pipefd[1]);
  std::uint64_t chunks = 0;
  while (chunks < 10) ASSERT_EQ(::read(pipefd[0], &chunks, sizeof(chunks)), static_cast<ssize_t>(sizeof(chunks)));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(pipefd[0]);
  ASSERT_TRUE(WIFSIGNALED(status));

  // The path was never written; every completed chunk of the .part file
  // reads back; each topic is a gap-free run from 1.
  EXPECT_FALSE(fs::exists(path));
  Status s;
  const TopicCounts c = read_counts(part.string(), &s);
  EXPECT_EQ(s.code, StatusCode::Truncated) << s.str();
  EXPECT_GE(c.total, 10U * (64 * 1024) / 7000);  // 10 chunks of 64 KiB, messages under 7 KB
  for (const auto& [topic, seqs] : c.sequences) {
    for (std::size_t i = 0; i < seqs.size(); ++i) ASSERT_EQ(seqs[i], i + 1) << topic;
  }
  RecoverReport rep;
  ASSERT_TRUE(recover(part.string(), fixed.string(), {}, rep).ok());
  EXPECT_EQ(rep.messages, c.total);
  Reader r;
  ASSERT_TRUE(r.open(fixed.string()).ok());
  EXPECT_TRUE(r.complete());
  EXPECT_TRUE(r.verify().ok());
  EXPECT_EQ(r.summary().statistics.message_count, c.total);
}

// ---------------------------------------------------------------------------- replay

// Echoes every scan with a count, and ticks every 250 ms of sim time.
class ScanCounter : public bus::Node {
 public:
  explicit ScanCounter(bus::NodeOptions o) : Node(std::move(o)) {
    echo_ = create_publisher<std_msgs::msg::String>("echo");
    tick_ = create_publisher<std_msgs::msg::String>("tick");
    sub_ = create_subscription<tinyline_msgs::msg::LineScan>(
        "scan", bus::QoS::reliable(10), [this](const tinyline_msgs::msg::LineScan& m) {
          auto out = std::make_unique<std_msgs::msg::String>();
          out->data = "scan " + std::to_string(m.set_index) + " #" + std::to_string(++count_) + " at " +
                      std::to_string(now().ns);
          echo_->publish(std::move(out));
        });
    timer_ = create_timer(250ms, [this] {
      auto out = std::make_unique<std_msgs::msg::String>();
      out->data = "tick after " + std::to_string(count_) + " scans";
      tick_->publish(std::move(out));
    });
  }

 private:
  int count_ = 0;
  std::shared_ptr<bus::Publisher<std_msgs::msg::String>> echo_, tick_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> sub_;
  std::shared_ptr<bus::Timer> timer_;
};

// 100 scans from t = 5 s at irregular 8-12 ms spacing, plus a topic of an unknown type.
std::vector<std::uint8_t> scan_bag(Timestamp* last = nullptr) {
  ros2::Ros2Writer w;
  MemoryWritable out;
  EXPECT_TRUE(w.open(std::make_unique<WritableRef>(out), WriterOptions{}).ok());
  ChannelId scans;
  EXPECT_TRUE(w.add_topic("/tiny/scan", msg::type_support<tinyline_msgs::msg::LineScan>(), scans).ok());
  Schema unknown{0, "foo_msgs/msg/Bar", "ros2msg", "int32 x\n"};
  EXPECT_TRUE(w.writer().add_schema(unknown).ok());
  Channel uc = ros2::channel_for("/foo", unknown.id, {ros2::QosProfile{}});
  EXPECT_TRUE(w.writer().add_channel(uc).ok());
  Timestamp t = 5'000'000'000ULL;
  for (std::uint32_t i = 0; i < 100; ++i) {
    t += 8'000'000ULL + (i * 7919ULL) % 5'000'000ULL;
    EXPECT_TRUE(w.write(scans, *line_scan(i), t, t).ok());
    if (i % 10 == 0) {
      static constexpr std::array<std::uint8_t, 8> kJunk{0, 1, 0, 0, 42, 0, 0, 0};
      EXPECT_TRUE(w.write_serialized(uc.id, kJunk, t, t).ok());
    }
  }
  EXPECT_TRUE(w.close().ok());
  if (last) *last = t;
  return out.take();
}

ReplayResult replay_scans(std::int64_t tail_ns = 0) {
  ReplayOptions ro;
  ro.tail_ns = tail_ns;
  Replay replay(std::make_unique<MemoryReadable>(scan_bag()), ro);
  replay.add<ScanCounter>("counter", {{"scan", "/tiny/scan"}});
  return replay.run();
}

TEST(Replay, TimersFireOnSimTimeFromTheFirstMessageWithExactCounts) {
  Timestamp last = 0;
  (void)scan_bag(&last);
  const ReplayResult out = replay_scans();
  ASSERT_TRUE(out.status.ok()) << out.status.str();
  EXPECT_EQ(out.replayed, 100U);
  ASSERT_EQ(out.skipped_topics.size(), 1U);
  EXPECT_NE(out.skipped_topics[0].find("foo_msgs/msg/Bar"), std::string::npos);
  ASSERT_EQ(out.count("/echo"), 100U);
  const auto echoes = out.messages<std_msgs::msg::String>("/echo");
  EXPECT_EQ(echoes.front()->data.rfind("scan 0 #1 at ", 0), 0U) << echoes.front()->data;
  EXPECT_EQ(echoes.back()->data.rfind("scan 99 #100 at ", 0), 0U) << echoes.back()->data;
  // Ticks every 250 ms of sim time from the first message, none after the last.
  const auto ticks =
      std::count_if(out.captured.begin(), out.captured.end(), [](const Captured& c) { return c.topic == "/tick"; });
  const bus::Time first = out.captured.front().time;  // the first echo, at the first message
  const std::int64_t span = static_cast<std::int64_t>(last) - first.ns;
  EXPECT_EQ(ticks, span / 250'000'000);
  std::int64_t k = 0;
  for (const auto& c : out.captured) {
    if (c.topic != "/tick") continue;
    EXPECT_EQ(c.time.ns, first.ns + (++k) * 250'000'000);
  }
  EXPECT_THROW((void)out.messages<tinyline_msgs::msg::LineScan>("/echo"), std::invalid_argument);

  // A tail keeps sim time going after the last message.
  const ReplayResult longer = replay_scans(1'000'000'000);
  EXPECT_EQ(longer.count("/tick"), static_cast<std::size_t>((span + 1'000'000'000) / 250'000'000));
}

TEST(Replay, SameBagSameNodesSameOutputEveryRun) {
  const std::string a = replay_scans().to_yaml();
  for (int run = 0; run < 3; ++run) EXPECT_EQ(replay_scans().to_yaml(), a);
  EXPECT_NE(a.find("topic: \"/tick\""), std::string::npos);
}

TEST(Replay, RefusesNodesOfAnotherContext) {
  Replay replay(std::make_unique<MemoryReadable>(scan_bag()));
  auto other = sim_context();
  EXPECT_THROW(replay.add_node(std::make_shared<ScanCounter>(opts(other, "x"))), std::invalid_argument);
}

// ---------------------------------------------------------------------------- player

// Counts what arrives; signals when a target is reached.
struct Counter {
  std::mutex mu;
  std::condition_variable cv;
  std::map<std::string, std::uint64_t> n;
  std::vector<std::uint32_t> set_index;
  bus::Time last_clock;
  bool wait_for(const std::string& topic, std::uint64_t count) {
    std::unique_lock lk(mu);
    return cv.wait_for(lk, 60s, [&] { return n[topic] >= count; });
  }
};

TEST(Player, PlaysEveryMessageInOrderAndDrivesSimTime) {
  const fs::path path = out_dir() / "play.mcap";
  {
    std::ofstream f(path, std::ios::binary);
    const auto bytes = scan_bag();
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  auto ctx = sim_context();
  bus::SingleThreadedExecutor exec(ctx->clock());
  auto counter = std::make_shared<Counter>();
  auto listener = std::make_shared<bus::Node>(opts(ctx, "listener"));
  auto s1 = listener->create_subscription<tinyline_msgs::msg::LineScan>(
      "/tiny/scan", bus::QoS::reliable(100000), [counter](const tinyline_msgs::msg::LineScan& m) {
        std::lock_guard lk(counter->mu);
        counter->set_index.push_back(m.set_index);
        ++counter->n["/tiny/scan"];
        counter->cv.notify_all();
      });
  auto s2 = listener->create_subscription<rosgraph_msgs::msg::Clock>(
      "/clock", bus::QoS::reliable(100000), [counter](const rosgraph_msgs::msg::Clock& m) {
        std::lock_guard lk(counter->mu);
        counter->last_clock = bus::Time::from_msg(m.clock);
        ++counter->n["/clock"];
      });
  PlayerOptions po;
  po.path = path.string();
  po.rate = 0;  // as fast as possible
  po.clock = true;
  auto player = std::make_shared<Player>(opts(ctx, "player"), po);
  exec.add_node(listener);
  exec.add_node(player);
  std::thread spinner([&] { exec.spin(); });
  ASSERT_TRUE(player->wait_finished(60s));
  ASSERT_TRUE(counter->wait_for("/tiny/scan", 100));
  exec.stop();
  spinner.join();
  const PlayerStats st = player->stats();
  EXPECT_TRUE(st.status.ok()) << st.status.str();
  EXPECT_EQ(st.published, 100U);
  EXPECT_EQ(st.failed, 0U);
  std::vector<std::uint32_t> want(100);
  for (std::uint32_t i = 0; i < 100; ++i) want[i] = i;
  EXPECT_EQ(counter->set_index, want);
  EXPECT_EQ(ctx->clock().now().ns, static_cast<std::int64_t>(st.bag_end));  // sim time followed the bag
  EXPECT_GE(counter->n["/clock"], 100U);
  player->stop();
}

TEST(Player, LoopsAndFiltersTopicsAndStartsAtAnOffset) {
  const fs::path path = out_dir() / "play_loop.mcap";
  {
    std::ofstream f(path, std::ios::binary);
    const auto bytes = scan_bag();
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  auto ctx = bus::Context::create();
  bus::SingleThreadedExecutor exec(ctx->clock());
  auto counter = std::make_shared<Counter>();
  auto listener = std::make_shared<bus::Node>(opts(ctx, "listener"));
  auto sub = listener->create_subscription<tinyline_msgs::msg::LineScan>(
      "/tiny/scan", bus::QoS::reliable(1000), [counter](const tinyline_msgs::msg::LineScan& m) {
        std::lock_guard lk(counter->mu);
        counter->set_index.push_back(m.set_index);
        ++counter->n["/tiny/scan"];
        counter->cv.notify_all();
      });
  // Skip the first 0.5 s; the first messages lie ~10 ms apart, so about half remain.
  auto player = std::make_shared<Player>(opts(ctx, "player")
                                             .param("path", path.string())
                                             .param("rate", 0.0)
                                             .param("loop", true)
                                             .param("start_offset_s", 0.5)
                                             .param("topics", std::vector<std::string>{"/tiny/scan"}));
  exec.add_node(listener);
  exec.add_node(player);
  std::thread spinner([&] { exec.spin(); });
  Reader r;
  ASSERT_TRUE(r.open(path.string()).ok());
  const Timestamp from = r.summary().statistics.message_start_time + 500'000'000ULL;
  std::vector<std::uint32_t> pass;
  ASSERT_TRUE(r.for_each({{"/tiny/scan"}, from}, [&](const MessageView& v) {
                 tinyline_msgs::msg::LineScan m;
                 EXPECT_TRUE(msg::deserialize(v.message.data, m));
                 pass.push_back(m.set_index);
                 return true;
               }).ok());
  ASSERT_GT(pass.size(), 20U);
  ASSERT_LT(pass.size(), 80U);
  ASSERT_TRUE(counter->wait_for("/tiny/scan", 3 * pass.size()));
  player->stop();
  exec.stop();
  spinner.join();
  EXPECT_GE(player->stats().loops, 2U);
  std::lock_guard lk(counter->mu);
  for (std::size_t i = 0; i < 3 * pass.size(); ++i) ASSERT_EQ(counter->set_index[i], pass[i % pass.size()]) << i;
}

// The recorder serializes into buffers the writer thread gives back, so steady
// traffic stops asking the kernel for fresh pages; the bytes written are the same.
TEST(AsyncWriter, RecyclesWrittenBuffersPerTopicWithinItsBudget) {
  MemoryWritable sink;
  AsyncWriter w;
  AsyncWriterOptions o;
  o.recycle_per_topic = 2;
  o.max_recycled_bytes = 3 * 16384;
  ASSERT_TRUE(w.open(std::make_unique<WritableRef>(sink), o).ok());
  const auto scans = w.add_topic("/tiny/scan", msg::type_support<tinyline_msgs::msg::LineScan>());
  const auto other = w.add_topic("/other", msg::type_support<tinyline_msgs::msg::LineScan>());
  EXPECT_EQ(w.take_buffer(scans).capacity(), 0U);  // nothing written yet
  EXPECT_EQ(w.take_buffer(99).capacity(), 0U);     // an unknown topic is no error
  for (std::uint32_t i = 0; i < 3; ++i) {
    std::vector<std::uint8_t> cdr;  // fresh (taking here would race the writer thread's returns)
    msg::serialize(*line_scan(i), cdr);
    cdr.reserve(16384);  // a known capacity (a line scan is about 4.9 KB), to check the byte budget
    ASSERT_TRUE(w.push(scans, std::move(cdr), 1000 + i, 1000 + i, i));
  }
  ASSERT_TRUE(w.close().ok());
  // Two kept (recycle_per_topic), cleared, with their capacity; none for the other topic.
  auto a = w.take_buffer(scans);
  auto b = w.take_buffer(scans);
  EXPECT_TRUE(a.empty());
  EXPECT_EQ(a.capacity(), 16384U);
  EXPECT_EQ(b.capacity(), 16384U);
  EXPECT_EQ(w.take_buffer(scans).capacity(), 0U);
  EXPECT_EQ(w.take_buffer(other).capacity(), 0U);

  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(std::span<const std::uint8_t>(sink.data()))).ok());
  std::uint32_t n = 0;
  ASSERT_TRUE(r.for_each({}, [&](const MessageView& v) {
                 tinyline_msgs::msg::LineScan m;
                 EXPECT_TRUE(msg::deserialize(v.message.data, m).ok);
                 EXPECT_EQ(m.set_index, n);
                 ++n;
                 return true;
               }).ok());
  EXPECT_EQ(n, 3U);
}

TEST(AsyncWriter, KeepsNoBuffersPastItsByteBudget) {
  MemoryWritable sink;
  AsyncWriter w;
  AsyncWriterOptions o;
  o.max_recycled_bytes = 16383;  // one byte less than the one buffer
  ASSERT_TRUE(w.open(std::make_unique<WritableRef>(sink), o).ok());
  const auto scans = w.add_topic("/tiny/scan", msg::type_support<tinyline_msgs::msg::LineScan>());
  std::vector<std::uint8_t> cdr;
  msg::serialize(*line_scan(0), cdr);
  cdr.reserve(16384);
  ASSERT_TRUE(w.push(scans, std::move(cdr), 1, 1, 0));
  ASSERT_TRUE(w.close().ok());
  EXPECT_EQ(w.take_buffer(scans).capacity(), 0U);
}

}  // namespace
}  // namespace tinyline::bag
