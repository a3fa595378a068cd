// SPDX-License-Identifier: Apache-2.0
// The DDS transport of the bus: a node that mirrors chosen topics of its
// process onto DDS and back.
//
//   local publisher --shared_ptr--> local subscribers          (zero copy, as before)
//                   \--> topic tap: serialize once --> DDS writer "rt/<topic>"
//   DDS reader "rt/<topic>" --> Cyclone's receive thread: deserialize once --> local subscribers
//
// Only topics with a local endpoint get DDS endpoints: a DDS writer when the
// process publishes the topic, a reader when it subscribes to it. Sending
// happens inside publish(), on the publisher's thread, after the local
// subscribers have the message (as in ROS 2); a writer with no matched reader
// skips serialization entirely. Receiving happens on Cyclone's receive thread
// itself (a data-available listener): it takes each sample, deserializes it
// and queues it for the subscribers' executor, with no thread in between;
// then, when the executor is running and a subscriber's callback group may
// run inline (bus::InlineDelivery: its callbacks proved short on the workers
// and never slept long inline), it hands the group to the bridge's inline
// runner (bus::InlineRunner), a thread of ours that runs the callback at
// once, instead of waking a worker. No user callback ever runs on Cyclone's
// thread: one that blocks holds the runner at most its bound (20 ms) before a
// fresh runner thread takes over. Cyclone's thread must never block (it also
// handles acknowledgements for every topic), so while
// a reliable local subscriber's queue is full the bridge's own thread takes
// over the topic and waits for room, leaving the rest in the DDS reader's
// history: back-pressure reaches the remote writer as before. One topic's
// samples are delivered by one thread at a time, in the order the reader
// holds them (per remote writer, its publish order). Messages the bridge
// injects carry its origin and its tap ignores that origin, so nothing is
// echoed back; DDS readers ignore writers of their own participant.
//
// QoS maps one to one (keep-last depth or keep-all, reliable or best effort,
// volatile or transient local), so DDS matching rules apply across processes
// exactly as in ROS 2: a best-effort publisher does not match a reliable
// subscriber. Mismatches are logged with the policy that failed.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/dds/participant.hpp>
#include <tinyline/dds/settings.hpp>

namespace tinyline::dds {

struct BridgeAccess;
namespace detail {
class RosGraph;
struct NodeEntities;
}  // namespace detail

/// Which topics of a process travel over DDS.
struct TopicSelection {
  bool all = false;                 ///< every topic with a local endpoint
  std::vector<std::string> topics;  ///< these absolute names (in addition)

  bool selects(const std::string& topic) const;
};

struct BridgeOptions {
  Settings settings;
  TopicSelection selection;
  std::string node_name = "dds_bridge";  ///< the bridge's node in the local graph
};

/// What one bridged topic has done so far.
struct LinkStats {
  std::string topic;
  std::string type;
  bool writer = false;  ///< a DDS writer exists (local publishers)
  bool reader = false;  ///< a DDS reader exists (local subscribers)
  EndpointQos writer_qos;
  EndpointQos reader_qos;
  std::size_t remote_readers = 0;   ///< matched now
  std::size_t remote_writers = 0;   ///< matched now
  std::uint64_t sent = 0;           ///< messages written to DDS
  std::uint64_t unmatched = 0;      ///< local messages not sent: no remote reader (volatile topics)
  std::uint64_t received = 0;       ///< messages from DDS published locally
  std::uint64_t decode_errors = 0;  ///< samples from DDS that did not decode (dropped, logged)
  std::uint64_t write_errors = 0;   ///< DDS writes that failed (logged)
  std::uint64_t incompatible = 0;   ///< remote endpoints refused for incompatible QoS
  std::uint64_t lost = 0;           ///< samples DDS reports lost on the way here (also in the topic's dropped)
  std::uint64_t stalls = 0;         ///< inline runs that held the runner past its bound (a fresh thread took over)
};

/// Remote endpoints a process expects before its nodes start.
struct PeerExpectation {
  std::string topic;
  std::size_t readers = 0;  ///< remote readers our writer must match
  std::size_t writers = 0;  ///< remote writers our reader must match
};

struct WaitResult {
  bool ok = false;
  std::string missing;  ///< what was still missing at the deadline
};

/// The QoS the bridge's DDS writer offers for these local publishers: the
/// strongest of them, so it serves every reader one of them would, and
/// always reliable (a reliable offer serves best-effort readers as well, so a
/// sensor_data() publisher reaches a default subscriber in another process
/// as it does in its own).
EndpointQos offered_qos(const std::vector<bus::QoS>& publishers);
/// The QoS its DDS reader requests for these local subscribers: reliability
/// and durability only if every one of them needs it (a stronger request
/// would refuse writers some of them accept), the deepest history, keep-all
/// if any of them queues reliably (back-pressure end to end).
EndpointQos requested_qos(const std::vector<bus::QoS>& subscribers);
/// Why DDS will not connect a writer offering `offered` to a reader
/// requesting `requested` (the ROS 2 / DDS rules), or empty if it will.
std::string incompatibility(const EndpointQos& offered, const EndpointQos& requested);

/// It needs no executor: sending runs on the publishers' threads, receiving on
/// Cyclone's (and its own while a subscriber queue is full); adding it to an
/// executor is harmless (on_start() calls start()).
class Bridge : public bus::Node {
 public:
  /// Creates the participant and starts the receive thread; DDS endpoints are
  /// created by start() (or on_start()). Throws DdsError.
  static std::shared_ptr<Bridge> create(const std::shared_ptr<bus::Context>& context, BridgeOptions options);
  ~Bridge() override;

  /// Creates DDS endpoints for every selected topic with local endpoints, and
  /// from now on for each new one as it appears. Idempotent.
  void start();
  void on_start() override { start(); }
  void on_stop() override;

  /// From now on, remote endpoints that go away are reported as departures
  /// (info), not losses (warnings): the graph is being stopped on purpose.
  void expect_departures() { departures_expected_.store(true); }

  /// Marks one more topic for DDS (absolute name).
  void bridge_topic(const std::string& topic);

  /// Blocks until every expectation is met or `timeout` passes. Lets a
  /// launched graph connect before its nodes publish, so the first message is
  /// not lost to discovery.
  [[nodiscard]] WaitResult wait_for_peers(const std::vector<PeerExpectation>& expected,
                                          std::chrono::milliseconds timeout);

  /// Publishes on /parameter_events each node's declared parameters (a
  /// ParameterEvent with them all as new_parameters), once a subscriber of
  /// /parameter_events has matched: nodes declare their parameters before the
  /// process joins the graph, and a volatile event with nobody listening is lost.
  void announce_parameters(const std::vector<std::shared_ptr<bus::Node>>& nodes);

  std::vector<LinkStats> stats() const;
  /// True when `id` is (or was) a thread of the bridge's inline runner: the
  /// thread subscribers' callbacks run on when they run where DDS delivers.
  bool is_inline_thread(std::thread::id id) const;
  /// The origin of messages this bridge injects (MessageInfo::origin).
  std::uint32_t origin() const { return origin_; }
  const Participant& participant() const { return *participant_; }

  struct Link;  // one bridged topic (bridge.cpp)

  Bridge(bus::NodeOptions node_options, BridgeOptions options);  // use create()

 private:
  friend struct BridgeAccess;
  void on_graph_change(const std::string& topic);
  /// Creates, replaces or deletes the topic's DDS endpoints to match its
  /// local publishers and subscribers now.
  void sync_topic(const std::string& topic);
  struct LocalEndpoints {
    std::vector<bus::QoS> publishers, subscribers;  ///< of nodes other than the bridge
  };
  LocalEndpoints local_endpoints(const std::string& topic);
  std::shared_ptr<Link> find_link(const std::string& topic) const;
  std::shared_ptr<Link> add_link(const std::string& topic, const std::shared_ptr<bus::Topic>& local);
  void sync_writer(Link& link, const std::shared_ptr<bus::Topic>& local, const std::vector<bus::QoS>& publishers);
  void sync_reader(Link& link, const std::vector<bus::QoS>& subscribers);
  void send(Link& link, const std::shared_ptr<const void>& msg);
  /// Delivers the samples `reader` holds. From the listener (`may_block`
  /// false) it never waits: a full reliable subscriber hands the topic to
  /// the back-pressure thread, which waits for room (`may_block` true).
  void drain(Link& link, std::int32_t reader, bool may_block);
  void take_available(Link& link, std::int32_t reader, bool may_block);
  void hand_over(Link& link);
  /// Says why shared memory does not serve this endpoint (its QoS).
  void explain_no_shared_memory(Link& link, const EndpointQos& qos, const char* who);
  void count_shared_memory_loss(Link& link);
  /// Counts and reports an inline run that outlived the runner's bound.
  void on_inline_stall(Link& link, const std::string& node, std::chrono::nanoseconds held);
  void backpressure_loop();
  void attach_graph(const std::weak_ptr<Bridge>& self);
  /// Remote endpoints as discovery reports them (every topic, matched or
  /// not): names a type mismatch on a topic of ours, and adopts a topic a
  /// local node wants (Graph::want) once another process publishes it.
  void watch_remote_endpoints();
  void read_remote_endpoints(std::int32_t reader, bool writers, bool only_new);
  void on_remote_endpoint(const std::string& dds_topic, const std::string& dds_type, const std::string& who,
                          bool writer);
  void adopt(const std::string& topic, const msg::TypeSupport& type);
  /// The process's nodes (but the bridge) with the DDS endpoints serving
  /// each, for ros_discovery_info.
  std::vector<detail::NodeEntities> ros_nodes();

  BridgeOptions options_;
  std::unique_ptr<Participant> participant_;
  std::uint32_t origin_ = 0;
  // Lock order: sync_mu_ (held across DDS calls that create or delete
  // entities) before mu_ (the link list, short). DDS listeners take neither:
  // deleting an entity waits for its listeners to return.
  mutable std::mutex sync_mu_;
  mutable std::mutex mu_;
  std::vector<std::shared_ptr<Link>> links_;
  bool started_ = false;
  bool stopped_ = false;
  int graph_listener_ = 0;
  std::atomic<bool> quit_{false};
  std::atomic<bool> departures_expected_{false};
  // Topics whose subscribers are full, for the back-pressure thread.
  std::mutex slow_mu_;
  std::condition_variable slow_cv_;
  std::vector<Link*> slow_links_;
  std::vector<std::string> resync_;  // topics whose endpoints changed inside a listener
  std::vector<std::pair<std::string, const msg::TypeSupport*>> adopt_;  // wanted topics found remotely
  std::atomic<std::int32_t> remote_pubs_{0}, remote_subs_{0};           // builtin-topic readers
  std::mutex remote_mu_;
  std::vector<std::string> mismatches_reported_;  // "topic|type" (under remote_mu_)
  std::thread backpressure_;
  // Runs the callbacks of what arrives, off Cyclone's thread (bus::InlineDelivery).
  std::unique_ptr<bus::InlineRunner> runner_;
  std::mutex match_mu_;  // guards match_events_ (bumped by DDS listeners)
  std::condition_variable matched_cv_;
  std::uint64_t match_events_ = 0;
  // Announces the nodes, forwards the log (ROS 2 graph citizenship); goes
  // first in the destructor: its thread calls ros_nodes().
  std::unique_ptr<detail::RosGraph> ros_graph_;
};

}  // namespace tinyline::dds
