// SPDX-License-Identifier: Apache-2.0
// The in-process graph: topics, their subscriptions, and the statistics the
// CLI shows. Publishing hands one std::shared_ptr<const T> to every
// subscription of the topic: zero copies on fan-out. Types are checked by
// identity of their msg::TypeSupport.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <vector>

#include <tinyline/bus/detail/message_ring.hpp>
#include <tinyline/bus/message_info.hpp>
#include <tinyline/bus/qos.hpp>
#include <tinyline/bus/time.hpp>
#include <tinyline/msg/type_support.hpp>

namespace tinyline::bus {

class CallbackGroup;
class Executor;

/// Whether a publish may wait for room in a full reliable queue. Transports
/// that deliver on a thread which must never block (DDS's receive thread)
/// publish with Never and stop taking messages while would_wait() holds.
enum class Wait { ForRoom, Never };

struct PublishStatus {
  std::size_t delivered = 0;  ///< subscriptions that took the message
  std::size_t failed = 0;     ///< reliable subscriptions that timed out (each reported)
  bool ok() const { return failed == 0; }
};

class SubscriptionBase : public std::enable_shared_from_this<SubscriptionBase> {
 public:
  SubscriptionBase(std::string topic, const msg::TypeSupport* type, QoS qos, std::shared_ptr<CallbackGroup> group);
  virtual ~SubscriptionBase() = default;
  SubscriptionBase(const SubscriptionBase&) = delete;
  SubscriptionBase& operator=(const SubscriptionBase&) = delete;

  const std::string& topic_name() const { return topic_; }
  const msg::TypeSupport& type() const { return *type_; }
  const QoS& qos() const { return qos_; }

  /// Publisher side. Returns false only for a reliable queue that stayed full
  /// for max_block (or could never drain because the publisher is the thread
  /// that drains it); `why` then says which. With Wait::Never a full reliable
  /// queue takes the message beyond its depth instead.
  bool enqueue(std::shared_ptr<const void> msg, const MessageInfo& info, std::string* why, Wait wait = Wait::ForRoom);
  /// True when a publisher would wait here now (a full reliable queue).
  bool would_wait();

  std::uint64_t received() const { return received_.load(std::memory_order_relaxed); }
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  std::uint64_t timeouts() const { return timeouts_.load(std::memory_order_relaxed); }
  std::size_t queued() const;

  /// Filled by the transport layer: messages whose origin equals this are not
  /// delivered (a bridge must not receive what it injected itself).
  std::uint32_t ignore_origin = 0;

  /// Detaches from the executor so no more callbacks run (node destruction).
  /// Returns how many queued messages it discarded.
  std::size_t cancel();
  /// Wakes reliable publishers waiting for room, so they look again whether
  /// to go on waiting (the executor that drains the queue may have stopped).
  void wake_publishers();

 protected:
  friend class CallbackGroup;
  /// Runs the callback; takes the message so the reference count is not touched.
  virtual void dispatch(std::shared_ptr<const void>&& msg, const MessageInfo& info) = 0;

 private:
  // The queue: a lock-free ring in the common case; a locked overflow deque
  // behind it for queues deeper than the ring and for the unbounded reliable
  // queues of a deterministic executor. While the overflow holds anything,
  // new messages go there too, so the order stays the publish order.
  static constexpr std::size_t kMaxRing = 1024;
  /// The stamp of the oldest queued message, if any (consumer side).
  std::optional<std::uint64_t> front_stamp();
  /// Takes the oldest queued message (the worker, or a keep-last publisher evicting it).
  bool pop(QueuedMessage* out);
  void push(QueuedMessage& m, std::uint64_t stamp);
  std::size_t size() const { return ring_.size() + overflow_size_.load(std::memory_order_seq_cst); }
  /// size() >= depth, cheaply on the publisher's side.
  bool full() {
    const std::size_t o = overflow_size_.load(std::memory_order_seq_cst);
    return o >= qos_.depth || ring_.size_reaches(qos_.depth - o);
  }
  /// Empties the queue; returns how many messages it held.
  std::size_t clear();
  /// Consumer side, after taking a message: wakes a reliable publisher waiting for room.
  void made_room();
  /// A reliable publisher facing a full queue: waits for room (running the
  /// subscriber itself when it may), up to max_block.
  enum class Room { Made, Gone, Failed };
  Room wait_for_room(CallbackGroup& g, std::string* why);
  /// Why a reliable publish failed: the executor draining the queue stops.
  std::string stopping_reason(const CallbackGroup& g) const;

  struct Stamped {
    QueuedMessage m;
    std::uint64_t stamp = 0;
  };

  // Read-mostly (both sides).
  const std::string topic_;
  const msg::TypeSupport* const type_;
  const QoS qos_;
  const std::shared_ptr<CallbackGroup> group_;
  std::atomic<bool> cancelled_{false};
  std::atomic<std::size_t> overflow_size_{0};  ///< changes only when the ring overflows
  detail::MessageRing ring_;
  // Slow paths: the overflow and reliable publishers waiting for room.
  std::mutex slow_mu_;
  std::deque<Stamped> overflow_;  // guarded by slow_mu_
  std::condition_variable room_;  // reliable: publishers wait here (with slow_mu_)
  std::atomic<int> waiting_{0};   // publishers inside room_.wait
  // Written by publishers on every message: kept off the lines the worker reads.
  alignas(64) std::atomic<std::uint64_t> received_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> timeouts_{0};
};

/// One topic of the graph.
class Topic {
 public:
  Topic(std::string name, const msg::TypeSupport* type) : name_(std::move(name)), type_(type) {}

  const std::string& name() const { return name_; }
  const msg::TypeSupport& type() const { return *type_; }

  PublishStatus publish(std::shared_ptr<const void> msg, const MessageInfo& info, std::string* why,
                        Wait wait = Wait::ForRoom);
  /// True when a publish would wait now: some reliable subscription is full.
  bool would_wait() const;

  void add_subscription(const std::shared_ptr<SubscriptionBase>& s);
  void remove_subscription(const SubscriptionBase* s);
  void add_publisher(const QoS& offered);
  void remove_publisher();

  /// A transport's view of every message published here: called on the
  /// publishing thread, after the local subscribers got it (the DDS bridge
  /// serializes and sends here, as ROS 2 does inside publish()). A new tap is
  /// first handed the latched messages. After remove_tap() returns, the tap
  /// is not running and will not run again.
  using Tap = std::function<void(const std::shared_ptr<const void>& msg, const MessageInfo& info)>;
  int add_tap(Tap tap);
  void remove_tap(int id);

  std::size_t publisher_count() const { return publishers_.load(); }
  std::size_t subscription_count() const;
  std::uint64_t published() const { return published_.load(std::memory_order_relaxed); }
  std::uint64_t next_sequence() { return sequence_.fetch_add(1, std::memory_order_relaxed) + 1; }
  /// Messages a transport knows were published elsewhere but never reached
  /// this process (DDS reported them lost on the way): part of dropped().
  void count_lost(std::uint64_t n) { lost_.fetch_add(n, std::memory_order_relaxed); }
  std::uint64_t lost() const { return lost_.load(std::memory_order_relaxed); }
  /// Sum over subscriptions (live and gone) of keep-last drops, plus lost().
  std::uint64_t dropped() const;
  std::uint64_t timeouts() const;

 private:
  using SubList = std::vector<std::shared_ptr<SubscriptionBase>>;
  std::shared_ptr<const SubList> snapshot() const;

  std::string name_;
  const msg::TypeSupport* type_;
  mutable std::mutex mu_;
  std::shared_ptr<const SubList> subs_ = std::make_shared<SubList>();
  std::atomic<std::size_t> publishers_{0};
  std::atomic<std::uint64_t> published_{0};
  std::atomic<std::uint64_t> sequence_{0};
  std::atomic<std::uint64_t> lost_{0};
  std::uint64_t gone_dropped_ = 0;  // from removed subscriptions (under mu_)
  std::uint64_t gone_timeouts_ = 0;
  // Transient-local: the last messages published, for late subscribers.
  std::atomic<std::size_t> latched_depth_{0};
  std::deque<QueuedMessage> latched_;
  // Taps: publish() holds taps_mu_ shared while calling them, so removal
  // waits for a call in progress. has_taps_ keeps the common case lock-free.
  std::shared_mutex taps_mu_;
  std::vector<std::pair<int, Tap>> taps_;
  std::atomic<bool> has_taps_{false};
  int next_tap_ = 1;
};

/// A row of `tinyline topic list` / the launch table.
struct TopicInfo {
  std::string name;
  std::string type;
  std::size_t publishers = 0;
  std::size_t subscriptions = 0;
  std::uint64_t published = 0;
  std::uint64_t dropped = 0;
  std::uint64_t timeouts = 0;
};

struct EndpointInfo {
  std::string topic;
  std::string type;
  QoS qos;
};

struct NodeInfo {
  std::string full_name;
  std::string type;  ///< registered "pkg/Type", or empty for ad-hoc nodes
  std::vector<EndpointInfo> publishers;
  std::vector<EndpointInfo> subscriptions;
};

class Graph {
 public:
  /// The topic `name`, created on first use. Throws std::invalid_argument if
  /// it exists with another type (naming both).
  std::shared_ptr<Topic> topic(const std::string& name, const msg::TypeSupport& type);
  /// The topic if it exists.
  std::shared_ptr<Topic> find(const std::string& name) const;

  std::vector<TopicInfo> topics() const;
  std::vector<NodeInfo> nodes() const;

  /// Called with every topic created from now on (and, at once, with every
  /// existing one). Used by "record all topics" and transport bridges.
  int on_topic(std::function<void(const std::shared_ptr<Topic>&)> fn);
  void remove_on_topic(int id);

  /// Called with a topic's name after a node adds a publisher or a
  /// subscription on it, and after a node with endpoints on it goes away, on
  /// the thread that did it. Transport bridges use it to mirror exactly the
  /// topics that have local endpoints, whenever they appear.
  int on_endpoints_changed(std::function<void(const std::string& topic)> fn);
  void remove_on_endpoints_changed(int id);
  /// Called by Node (never with a node's lock held).
  void endpoints_changed(const std::string& topic);

  /// A node wants this topic though nothing in the process publishes or
  /// subscribes to it yet (a recorder's `topics`): a transport that sees it
  /// published elsewhere creates it here, with the type it learns there.
  /// Tells the endpoint listeners.
  void want(const std::string& topic);
  bool wanted(const std::string& topic) const;
  std::vector<std::string> wants() const;

  // Node bookkeeping for introspection.
  void add_node(const void* key, std::function<NodeInfo()> describe);
  void remove_node(const void* key);

 private:
  mutable std::mutex mu_;
  std::vector<std::shared_ptr<Topic>> topics_;
  std::vector<std::pair<int, std::function<void(const std::shared_ptr<Topic>&)>>> listeners_;
  std::vector<std::pair<int, std::function<void(const std::string&)>>> endpoint_listeners_;
  std::vector<std::pair<const void*, std::function<NodeInfo()>>> nodes_;
  std::vector<std::string> wanted_;
  int next_listener_ = 1;
};

/// Counts per topic between two looks at the graph: rates for the live table.
class RateMonitor {
 public:
  struct Row {
    TopicInfo info;
    double rate_hz = 0.0;
  };
  /// Rates since the previous call (zero on the first call).
  std::vector<Row> sample(const Graph& g, Time wall_now);

 private:
  std::vector<std::pair<std::string, std::uint64_t>> last_counts_;
  Time last_time_;
  bool have_last_ = false;
};

}  // namespace tinyline::bus
