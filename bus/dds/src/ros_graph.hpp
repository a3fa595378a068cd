// SPDX-License-Identifier: Apache-2.0
// What a process with DDS on tells the ROS 2 graph besides its topics, as an
// rmw_cyclonedds participant does:
//   ros_discovery_info  rmw_dds_common/msg/ParticipantEntitiesInfo: the
//                       participant's nodes and the ids (GIDs) of the DDS
//                       readers and writers serving each, republished
//                       whenever they change (reliable, transient local, depth 1)
//   /rosout             rcl_interfaces/msg/Log: every record the process's log
//                       sink is given (reliable, transient local, depth 1000,
//                       lifespan 10 s, as rcl's rosout publisher)
//   /parameter_events   rcl_interfaces/msg/ParameterEvent: each node's declared
//                       parameters (reliable, volatile, depth 1000), once a
//                       subscriber is there to hear them
// DDS writes happen on a thread of its own: a log record may come from any
// thread, Cyclone's listeners included, holding any lock.
#pragma once

#include <dds/dds.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bus/logging.hpp>
#include <tinyline/bus/params.hpp>
#include <tinyline/dds/participant.hpp>
#include <tinyline/msg/rcl_interfaces/log.hpp>
#include <tinyline/msg/rcl_interfaces/parameter_event.hpp>

#include "entities.hpp"

namespace tinyline::dds::detail {

/// A DDS entity's id as ROS 2 graph caches key it: its GUID, prefix then entity id.
using Gid = std::array<std::uint8_t, 16>;
Gid gid_of(dds_entity_t entity);

/// One node of this process and the DDS endpoints that serve it.
struct NodeEntities {
  std::string ns;    ///< "/" or "/a/b"
  std::string name;  ///< "laser"
  std::vector<Gid> readers, writers;
};

/// "/a/b/node" -> {"/a/b", "node"}; "/node" -> {"/", "node"}.
NodeEntities split_full_name(const std::string& full_name);
/// The logger name rcl gives a node: "/a/b/node" -> "a.b.node".
std::string ros_logger_name(const std::string& full_name);

/// A ParameterEvent announcing `params` of the node `node` as new, stamped now.
rcl_interfaces::msg::ParameterEvent declared_parameters(const std::string& node,
                                                        const std::vector<bus::ParamDescriptor>& params);

/// A DDS writer of a mirrored ROS 2 type on a topic that is not on the bus.
class TypedWriter {
 public:
  TypedWriter(Participant& p, const std::string& dds_topic, const msg::TypeSupport& type, const EndpointQos& qos,
              std::chrono::nanoseconds lifespan, dds_listener_t* listener);
  ~TypedWriter();
  TypedWriter(const TypedWriter&) = delete;
  TypedWriter& operator=(const TypedWriter&) = delete;

  Gid gid() const { return gid_of(writer_); }
  /// Serializes and writes `msg` (of the writer's type); false if DDS refused it.
  bool write(const void* msg);

 private:
  const msg::TypeSupport* type_;
  TopicHandle topic_;
  dds_entity_t writer_ = 0;
};

class RosGraph {
 public:
  /// `nodes` lists the process's nodes with their endpoints now; it is called
  /// on the graph's own thread.
  RosGraph(Participant& p, const bus::LogSink* sink, std::function<std::vector<NodeEntities>()> nodes);
  ~RosGraph();
  RosGraph(const RosGraph&) = delete;
  RosGraph& operator=(const RosGraph&) = delete;

  /// Nodes or their endpoints changed: announce them again (coalesced).
  void graph_changed();
  /// Parameter declarations to publish once /parameter_events has a reader.
  void set_parameter_events(std::vector<rcl_interfaces::msg::ParameterEvent> events);
  /// Records given to /rosout that did not fit the queue (a burst beyond its depth).
  std::uint64_t dropped_logs() const;

  /// Called by the /parameter_events writer's listener.
  void reader_matched();

 private:
  void on_log(const bus::LogRecord& r);
  void run();
  void announce();

  // Before the writers: their listeners may fire while they are being made.
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool quit_ = false;
  bool dirty_ = true;
  bool param_reader_ = false;
  std::deque<rcl_interfaces::msg::Log> logs_;
  std::uint64_t dropped_logs_ = 0;
  std::vector<rcl_interfaces::msg::ParameterEvent> params_;

  std::function<std::vector<NodeEntities>()> nodes_;
  Gid participant_gid_{};
  TypedWriter discovery_, rosout_, parameter_events_;
  int observer_ = 0;
  std::thread thread_;  // joined by the destructor before anything above goes
};

}  // namespace tinyline::dds::detail
