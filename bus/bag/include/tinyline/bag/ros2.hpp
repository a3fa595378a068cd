// SPDX-License-Identifier: Apache-2.0
// The ros2 profile of MCAP, as rosbag2 writes it: schema encoding "ros2msg"
// (the .msg text with its dependencies appended, each after a line of 80 '='
// and "MSG: pkg/Type"), message encoding "cdr", and the channel metadata key
// "offered_qos_profiles" (a YAML list of QoS profiles). Ros2Writer adds typed
// writing on top of the generic Writer.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/writer.hpp>
#include <tinyline/msg/type_support.hpp>

namespace tinyline::bag::ros2 {

inline constexpr std::string_view kProfile = "ros2";
inline constexpr std::string_view kSchemaEncoding = "ros2msg";
inline constexpr std::string_view kMessageEncoding = "cdr";
inline constexpr std::string_view kQosKey = "offered_qos_profiles";

/// The parts of an rmw QoS profile rosbag2 records (values as rmw numbers them).
struct QosProfile {
  enum class History { KeepLast = 1, KeepAll = 2 };
  enum class Reliability { Reliable = 1, BestEffort = 2 };
  enum class Durability { TransientLocal = 1, Volatile = 2 };
  History history = History::KeepLast;
  std::size_t depth = 10;
  Reliability reliability = Reliability::Reliable;
  Durability durability = Durability::Volatile;
};

/// The YAML list rosbag2 stores under offered_qos_profiles.
std::string offered_qos_profiles_yaml(const std::vector<QosProfile>& profiles);

/// Schema record content for a message type.
Schema schema_for(const msg::TypeSupport& type);
/// Channel record content for a topic (schema id filled by the caller's Writer::add_schema).
Channel channel_for(std::string topic, SchemaId schema_id, const std::vector<QosProfile>& offered);

/// The type support of a channel's schema (by its name), or nullptr with `why`
/// set: no schema, a non-ros2 encoding, or a type this build does not know.
const msg::TypeSupport* type_support_for(const Schema* schema, const Channel& channel, std::string* why = nullptr);

/// Writes ROS 2 bags: one call per topic, then typed or serialized messages.
class Ros2Writer {
 public:
  Status open(const std::string& path, WriterOptions options = {});
  Status open(std::unique_ptr<Writable> out, WriterOptions options = {});

  /// Registers a topic of a type; `id` receives the channel to write with.
  Status add_topic(const std::string& topic, const msg::TypeSupport& type, ChannelId& id,
                   const std::vector<QosProfile>& offered = {QosProfile{}});

  template <class T>
  Status write(ChannelId channel, const T& message, Timestamp log_time, Timestamp publish_time,
               std::uint32_t sequence = 0) {
    return write(channel, msg::type_support<T>(), &message, log_time, publish_time, sequence);
  }
  /// Type-erased: `message` must be of the channel's type.
  Status write(ChannelId channel, const msg::TypeSupport& type, const void* message, Timestamp log_time,
               Timestamp publish_time, std::uint32_t sequence = 0);
  /// Encapsulated CDR bytes as they are.
  Status write_serialized(ChannelId channel, std::span<const std::uint8_t> cdr, Timestamp log_time,
                          Timestamp publish_time, std::uint32_t sequence = 0);

  Status close() { return writer_.close(); }
  Writer& writer() { return writer_; }

 private:
  Writer writer_;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace tinyline::bag::ros2
