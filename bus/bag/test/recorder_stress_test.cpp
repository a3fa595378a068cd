// SPDX-License-Identifier: Apache-2.0
// The recorder under overload: fast publishers on several threads, a tiny
// subscription queue, a small write queue, an executor with several threads
// stopped while traffic still flows. Whatever it cannot take it must drop as
// whole messages and count per topic: every message published is either in
// the bag, intact, or in the count. Runs under TSan in the tsan preset.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <thread>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

namespace tinyline::bag {
namespace {

using StringMsg = std_msgs::msg::String;

bus::NodeOptions opts(const std::shared_ptr<bus::Context>& ctx, std::string name) {
  bus::NodeOptions o;
  o.name = std::move(name);
  o.context = ctx;
  return o;
}

// "/topic:k:padding": the publisher's counter and some bulk for the write queue.
std::unique_ptr<StringMsg> tagged(const std::string& topic, int k) {
  auto m = std::make_unique<StringMsg>();
  m->data = topic + ":" + std::to_string(k) + ":" + std::string(static_cast<std::size_t>(64 + k % 4096), 'x');
  return m;
}

// "/a: 3, /b: 7" -> {{"/a", 3}, {"/b", 7}}
std::map<std::string, std::uint64_t> parse_counts(const std::string& s) {
  std::map<std::string, std::uint64_t> out;
  std::size_t at = 0;
  while (at < s.size()) {
    const std::size_t colon = s.find(": ", at);
    const std::size_t comma = s.find(", ", colon);
    out[s.substr(at, colon - at)] =
        std::stoull(s.substr(colon + 2, comma == std::string::npos ? comma : comma - colon - 2));
    if (comma == std::string::npos) break;
    at = comma + 2;
  }
  return out;
}

struct Outcome {
  std::map<std::string, std::uint64_t> published;
  std::map<std::string, std::uint64_t> in_bag;
  std::map<std::string, std::uint64_t> dropped;  // from the bag's metadata
  std::uint64_t bad_messages = 0;                // torn, duplicated or out of order
  RecorderStats stats;
  Status status;
};

Outcome run_overload(std::size_t queue_depth, int threads) {
  auto ctx = bus::Context::create(bus::ContextOptions{bus::ClockType::Wall, std::make_shared<bus::CaptureSink>()});
  auto sink = std::make_unique<MemoryWritable>();
  MemoryWritable* mem = sink.get();
  RecorderOptions ro;
  ro.queue_depth = queue_depth;
  ro.writer.max_queue_bytes = 1 << 20;  // the smallest the parameter allows: the write queue may refuse some too
  ro.writer.writer.chunk_size_bytes = 16 * 1024;
  auto recorder = std::make_shared<Recorder>(opts(ctx, "recorder"), ro, std::make_unique<WritableRef>(*mem));
  bus::MultiThreadedExecutor ex(ctx->clock(), threads);
  ex.add_node(recorder);
  constexpr int kPublishers = 4;
  constexpr int kEach = 3000;
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::vector<std::shared_ptr<bus::Publisher<StringMsg>>> pubs;
  for (int p = 0; p < kPublishers; ++p) {
    nodes.push_back(std::make_shared<bus::Node>(opts(ctx, "source" + std::to_string(p))));
    pubs.push_back(nodes.back()->create_publisher<StringMsg>("/s" + std::to_string(p % 3)));  // two share /s0
    ex.add_node(nodes.back());
  }
  recorder->start();  // subscribed to every topic before the first message (on_start() then does nothing)
  std::thread spinner([&] { ex.spin(); });
  std::vector<std::thread> threads_out;
  std::vector<std::map<std::string, std::uint64_t>> counts(kPublishers);
  for (int p = 0; p < kPublishers; ++p) {
    threads_out.emplace_back([&, p] {
      const std::string topic = pubs[static_cast<std::size_t>(p)]->topic_name();
      for (int k = 0; k < kEach; ++k) {
        pubs[static_cast<std::size_t>(p)]->publish(tagged(topic + "#" + std::to_string(p), k));
        ++counts[static_cast<std::size_t>(p)][topic];
      }
    });
  }
  // Stop while the sources are still publishing: a stop must end the spin
  // however full the queues are.
  while (recorder->stats().received < 2000) std::this_thread::yield();
  ex.stop();
  spinner.join();
  for (auto& t : threads_out) t.join();
  Outcome out;
  for (const auto& c : counts)
    for (const auto& [t, n] : c) out.published[t] += n;
  out.status = recorder->stop();
  out.stats = recorder->stats();
  nodes.clear();

  Reader r;
  EXPECT_TRUE(r.open(std::make_unique<MemoryReadable>(mem->data())).ok());
  std::map<std::string, int> last;  // per publisher tag
  const Status rs = r.for_each({}, [&](const MessageView& v) {
    ++out.in_bag[v.channel->topic];
    StringMsg m;
    try {
      auto decoded = msg::type_support<StringMsg>().deserialize(v.message.data);
      m = *std::static_pointer_cast<const StringMsg>(decoded);
    } catch (const std::exception&) {
      ++out.bad_messages;
      return true;
    }
    const std::size_t c1 = m.data.find(':');
    const std::size_t c2 = m.data.find(':', c1 + 1);
    if (c1 == std::string::npos || c2 == std::string::npos ||
        m.data.compare(0, v.channel->topic.size(), v.channel->topic) != 0) {
      ++out.bad_messages;
      return true;
    }
    const std::string who = m.data.substr(0, c1);
    const int k = std::stoi(m.data.substr(c1 + 1, c2 - c1 - 1));
    const bool intact = m.data.size() == c2 + 1 + static_cast<std::size_t>(64 + k % 4096);
    auto it = last.find(who);
    if (!intact || (it != last.end() && k <= it->second)) ++out.bad_messages;
    last[who] = k;
    return true;
  });
  EXPECT_TRUE(rs.ok()) << rs.str();
  Metadata md;
  EXPECT_TRUE(r.read_metadata(r.summary().metadata_indexes.at(0), md).ok());
  out.dropped = parse_counts(md.metadata.at("dropped_by_topic"));
  return out;
}

TEST(RecorderStress, FastPublishersTinyQueuesManyThreadsEveryMessageRecordedOrCountedPerTopic) {
  for (std::size_t depth : {1, 2, 5, 10}) {
    SCOPED_TRACE("queue_depth " + std::to_string(depth));
    const Outcome o = run_overload(depth, 4);
    EXPECT_TRUE(o.status.ok()) << o.status.str();
    EXPECT_EQ(o.bad_messages, 0U);
    ASSERT_EQ(o.published.size(), 3U);
    std::uint64_t written = 0;
    for (const auto& [topic, n] : o.published) {
      SCOPED_TRACE(topic);
      const std::uint64_t kept = o.in_bag.count(topic) ? o.in_bag.at(topic) : 0;
      const std::uint64_t lost = o.dropped.count(topic) ? o.dropped.at(topic) : 0;
      EXPECT_EQ(kept + lost, n) << "in the bag " << kept << ", counted as dropped " << lost;
      written += kept;
    }
    EXPECT_EQ(written, o.stats.written);
  }
}

}  // namespace
}  // namespace tinyline::bag
