// SPDX-License-Identifier: Apache-2.0
// Replay tests: a bag through a set of nodes, deterministically.
//
//   bag::Replay replay(TINYLINE_SOURCE_DIR "/test/data/scans.mcap");
//   replay.add<LineClusterer>("clusterer", {{"scan", "/tiny/scan"}});
//   const bag::ReplayResult out = replay.run();
//   ASSERT_TRUE(out.status.ok()) << out.status.str();
//   EXPECT_EQ(out.count("/clusters"), 42U);
//   const auto clusters = out.messages<tinyline_msgs::msg::Clusters>("/clusters");
//
// The nodes share a context on sim time and a DeterministicExecutor. Each bag
// message is published at its log time: sim time first advances to it (every
// timer due on the way fires at its own due time, and everything it triggers
// runs), then the message is published and every callback it triggers runs
// before the next one. Timers start counting at the first message. What the
// nodes publish is captured with its sim time, in publication order; the
// bag's own messages are not. Same bag, same nodes: same output, every run,
// exact counts (unlike rosbag2 playback, nothing is dropped before a
// subscriber matches, and time is never best-effort).
#pragma once

#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>

namespace tinyline::bag {

struct ReplayOptions {
  std::vector<std::string> topics;  ///< bag topics to publish; empty: every topic of a known type
  Timestamp start_time = 0;         ///< first log time to replay (inclusive) [ns]
  Timestamp end_time = std::numeric_limits<Timestamp>::max();  ///< last (exclusive) [ns]
  /// Keep advancing sim time this long after the last message, so timers that
  /// follow it fire [ns].
  std::int64_t tail_ns = 0;
  /// Also publish rosgraph_msgs/Clock on /clock at each message time.
  bool publish_clock = false;
  /// Topics to capture; empty: everything the nodes publish.
  std::vector<std::string> capture;
};

/// One message a node published during the replay.
struct Captured {
  std::string topic;
  const msg::TypeSupport* type = nullptr;
  bus::Time time;  ///< sim time of publication
  std::shared_ptr<const void> message;

  /// The message as T; throws std::invalid_argument if it is another type.
  template <class T>
  const T& as() const {
    if (type != &msg::type_support<T>()) {
      throw std::invalid_argument("message on " + topic + " is " + std::string(type->name) + ", not " +
                                  std::string(T::kTypeName));
    }
    return *static_cast<const T*>(message.get());
  }
};

struct ReplayResult {
  std::vector<Captured> captured;           ///< in publication order
  std::uint64_t replayed = 0;               ///< bag messages published
  std::vector<std::string> skipped_topics;  ///< bag topics not replayed (unknown types), with the reason
  Status status;                            ///< ok, or why the bag could not be read to the end

  std::size_t count(const std::string& topic) const;
  /// The messages captured on `topic`, as T (throws on a type mismatch).
  template <class T>
  std::vector<std::shared_ptr<const T>> messages(const std::string& topic) const {
    std::vector<std::shared_ptr<const T>> out;
    for (const auto& c : captured) {
      if (c.topic != topic) continue;
      (void)c.as<T>();
      out.push_back(std::static_pointer_cast<const T>(c.message));
    }
    return out;
  }
  /// Every captured message as YAML documents (topic, time, fields): handy for
  /// expected-output files kept next to a test.
  std::string to_yaml() const;
};

class Replay {
 public:
  /// Replays the bag at `path`.
  explicit Replay(const std::string& path, ReplayOptions options = {});
  /// Replays from any source (an in-memory bag in a test).
  explicit Replay(std::unique_ptr<Readable> source, ReplayOptions options = {});
  ~Replay();
  Replay(const Replay&) = delete;
  Replay& operator=(const Replay&) = delete;

  /// The context the nodes must be built with (sim time).
  const std::shared_ptr<bus::Context>& context() const { return context_; }

  /// Builds a node of type N in the replay's context and adds it.
  template <class N, class... Args>
  std::shared_ptr<N> add(bus::NodeOptions options, Args&&... args) {
    options.context = context_;
    auto node = std::make_shared<N>(std::move(options), std::forward<Args>(args)...);
    add_node(node);
    return node;
  }
  /// Builds a node of type N named `name` with these remaps.
  template <class N>
  std::shared_ptr<N> add(const std::string& name, std::vector<bus::Remap> remaps = {},
                         std::vector<bus::ParamOverride> params = {}) {
    bus::NodeOptions o;
    o.name = name;
    o.remaps = std::move(remaps);
    o.params = std::move(params);
    return add<N>(std::move(o));
  }
  /// Adds a node built elsewhere (it must use context()).
  void add_node(std::shared_ptr<bus::Node> node);

  /// Replays the bag once; call once per Replay.
  ReplayResult run();

 private:
  std::unique_ptr<Readable> source_;
  ReplayOptions options_;
  std::shared_ptr<bus::Context> context_;
  std::vector<std::shared_ptr<bus::Node>> nodes_;
  bool ran_ = false;
};

}  // namespace tinyline::bag
