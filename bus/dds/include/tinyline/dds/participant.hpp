// SPDX-License-Identifier: Apache-2.0
// One DDS domain participant of this process, and the raw endpoints the tools
// build on: a reader and a writer of encapsulated CDR on any DDS topic, and a
// snapshot of what discovery has seen. Cyclone DDS types stay out of these
// headers; entities are plain handles.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tinyline/dds/settings.hpp>

namespace tinyline::dds {

/// Who owns an endpoint, from the user data every tinyline endpoint carries
/// ("typehash=RIHS01_...;process=NAME;pid=N;host=H;"). The process is empty
/// for endpoints of other programs; ROS 2 (Iron and later) endpoints carry
/// the type hash too.
struct Identity {
  std::string process;
  long pid = 0;
  std::string host;
  std::string type_hash;  ///< the endpoint's REP 2011 type hash, if it says

  bool known() const { return !process.empty(); }
  /// "process 'driver' (pid 4242 on robot)" or "a participant that is not tinyline".
  std::string describe() const;
  std::string to_user_data() const;
  static Identity parse(std::string_view user_data);
};

/// The QoS of one DDS endpoint, in the terms of bus::QoS.
struct EndpointQos {
  bool reliable = true;          ///< reliable vs best effort
  bool transient_local = false;  ///< late joiners get the last `depth` samples
  bool keep_all = false;         ///< KEEP_ALL history (bus::QoS::reliable): the writer blocks when full
  int depth = 10;                ///< KEEP_LAST depth
  std::chrono::nanoseconds max_blocking = std::chrono::seconds(1);  ///< reliable writer: longest wait for room
  /// Reader: also take this participant's own writes. Cyclone 0.10 gives
  /// shared memory only to readers that do (iceoryx knows no ignore-local);
  /// the owner then drops its own samples itself (by publication handle).
  bool accept_local = false;
  std::string describe() const;
};

class Participant {
 public:
  /// Creates (or joins) the domain with the settings' configuration and a
  /// participant on it. Throws DdsError saying what Cyclone refused.
  explicit Participant(Settings settings);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  std::int32_t handle() const { return participant_; }
  const Settings& settings() const { return settings_; }
  const Identity& identity() const { return identity_; }
  /// Shared memory is on: the settings asked for it and a RouDi runs here.
  bool shared_memory() const { return shared_memory_; }

 private:
  Settings settings_;
  Identity identity_;
  bool shared_memory_ = false;
  std::int32_t participant_ = 0;
};

/// One sample as it came off the network.
struct RawSample {
  std::span<const std::uint8_t> cdr;  ///< encapsulated CDR (valid during the callback only)
  std::int64_t source_time_ns = 0;    ///< writer's timestamp
  std::uint64_t publication = 0;      ///< the writer's instance handle
};

/// A reader of a DDS topic that hands out its samples' bytes undecoded; works
/// for any type name, tinyline's or not.
class RawReader {
 public:
  RawReader(Participant& p, const std::string& dds_topic, const std::string& dds_type, const EndpointQos& qos);
  ~RawReader();
  RawReader(const RawReader&) = delete;
  RawReader& operator=(const RawReader&) = delete;

  /// Waits up to `timeout` for data, then calls `fn` for every sample
  /// available. Returns the number of samples.
  std::size_t take(std::chrono::nanoseconds timeout, const std::function<void(const RawSample&)>& fn);
  std::size_t matched_writers() const;
  /// Identities of the writers matched now.
  std::vector<Identity> matched_writer_identities() const;

 private:
  std::int32_t topic_ = 0, reader_ = 0, waitset_ = 0, cond_ = 0;
};

/// A writer of encapsulated CDR bytes on a DDS topic (tests, tools).
class RawWriter {
 public:
  RawWriter(Participant& p, const std::string& dds_topic, const std::string& dds_type, const EndpointQos& qos);
  ~RawWriter();
  RawWriter(const RawWriter&) = delete;
  RawWriter& operator=(const RawWriter&) = delete;

  /// Sends the bytes as they are (no check that they decode). Throws DdsError.
  void write(std::span<const std::uint8_t> encapsulated_cdr);
  std::size_t matched_readers() const;
  /// Blocks until at least `n` readers matched or `timeout` passed.
  bool wait_for_readers(std::size_t n, std::chrono::nanoseconds timeout);

 private:
  std::int32_t participant_ = 0, topic_ = 0, writer_ = 0;
  const void* sertype_ = nullptr;  // the domain's sertype of the topic
};

/// An endpoint discovery has seen (local or remote).
struct DiscoveredEndpoint {
  bool writer = false;
  std::string dds_topic;
  std::string dds_type;
  std::optional<std::string> topic;  ///< ROS name if dds_topic is "rt/..."
  std::optional<std::string> type;   ///< ROS type name if dds_type follows the convention
  EndpointQos qos;
  Identity owner;
  std::string participant;  ///< the participant's GUID in hex
};

/// Builtin-topic readers: who is out there.
class Discovery {
 public:
  explicit Discovery(Participant& p);
  ~Discovery();
  Discovery(const Discovery&) = delete;
  Discovery& operator=(const Discovery&) = delete;

  /// Every endpoint alive now, except this participant's own.
  std::vector<DiscoveredEndpoint> snapshot() const;
  /// Waits until the snapshot stops changing for `settle` (or `timeout`
  /// passes), then returns it. Discovery on loopback takes tens of ms.
  std::vector<DiscoveredEndpoint> settle(std::chrono::milliseconds settle, std::chrono::milliseconds timeout) const;
  /// Waits until `pred` holds for the snapshot (checked whenever discovery
  /// learns something) or `timeout` passes; returns the last snapshot.
  std::vector<DiscoveredEndpoint> wait_for(const std::function<bool(const std::vector<DiscoveredEndpoint>&)>& pred,
                                           std::chrono::milliseconds timeout) const;

 private:
  std::int32_t self_ = 0;
  std::int32_t publications_ = 0, subscriptions_ = 0;
};

}  // namespace tinyline::dds
