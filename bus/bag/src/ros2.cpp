// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/ros2.hpp>

#include <fmt/format.h>

namespace tinyline::bag::ros2 {

std::string offered_qos_profiles_yaml(const std::vector<QosProfile>& profiles) {
  if (profiles.empty()) return "[]";
  // rosbag2's layout; a zero duration means "unspecified" (the rmw default, infinite).
  std::string y;
  for (const auto& p : profiles) {
    y += fmt::format(
        "- history: {}\n"
        "  depth: {}\n"
        "  reliability: {}\n"
        "  durability: {}\n"
        "  deadline:\n    sec: 0\n    nsec: 0\n"
        "  lifespan:\n    sec: 0\n    nsec: 0\n"
        "  liveliness: 1\n"
        "  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n"
        "  avoid_ros_namespace_conventions: false\n",
        static_cast<int>(p.history), p.depth, static_cast<int>(p.reliability), static_cast<int>(p.durability));
  }
  y.pop_back();  // rosbag2 writes no trailing newline
  return y;
}

Schema schema_for(const msg::TypeSupport& type) {
  Schema s;
  s.name = std::string(type.name);
  s.encoding = std::string(kSchemaEncoding);
  s.data = std::string(type.definition);
  return s;
}

Channel channel_for(std::string topic, SchemaId schema_id, const std::vector<QosProfile>& offered) {
  Channel c;
  c.topic = std::move(topic);
  c.schema_id = schema_id;
  c.message_encoding = std::string(kMessageEncoding);
  c.metadata[std::string(kQosKey)] = offered_qos_profiles_yaml(offered);
  return c;
}

const msg::TypeSupport* type_support_for(const Schema* schema, const Channel& channel, std::string* why) {
  auto no = [&](std::string reason) -> const msg::TypeSupport* {
    if (why) *why = std::move(reason);
    return nullptr;
  };
  if (channel.message_encoding != kMessageEncoding) {
    return no(fmt::format("topic {} has message encoding '{}', not cdr", channel.topic, channel.message_encoding));
  }
  if (schema == nullptr) return no(fmt::format("topic {} has no schema", channel.topic));
  const msg::TypeSupport* ts = msg::find_type_support(schema->name);
  if (ts == nullptr) {
    return no(
        fmt::format("topic {} has type {}, which this build of tinyline does not know", channel.topic, schema->name));
  }
  return ts;
}

Status Ros2Writer::open(const std::string& path, WriterOptions options) {
  options.profile = std::string(kProfile);
  return writer_.open(path, std::move(options));
}

Status Ros2Writer::open(std::unique_ptr<Writable> out, WriterOptions options) {
  options.profile = std::string(kProfile);
  return writer_.open(std::move(out), std::move(options));
}

Status Ros2Writer::add_topic(const std::string& topic, const msg::TypeSupport& type, ChannelId& id,
                             const std::vector<QosProfile>& offered) {
  Schema s = schema_for(type);
  if (Status st = writer_.add_schema(s); !st.ok()) return st;
  Channel c = channel_for(topic, s.id, offered);
  if (Status st = writer_.add_channel(c); !st.ok()) return st;
  id = c.id;
  return {};
}

Status Ros2Writer::write(ChannelId channel, const msg::TypeSupport& type, const void* message, Timestamp log_time,
                         Timestamp publish_time, std::uint32_t sequence) {
  buffer_.clear();
  type.serialize(message, buffer_);
  return write_serialized(channel, buffer_, log_time, publish_time, sequence);
}

Status Ros2Writer::write_serialized(ChannelId channel, std::span<const std::uint8_t> cdr, Timestamp log_time,
                                    Timestamp publish_time, std::uint32_t sequence) {
  Message m;
  m.channel_id = channel;
  m.sequence = sequence;
  m.log_time = log_time;
  m.publish_time = publish_time;
  m.data = cdr;
  return writer_.write(m);
}

}  // namespace tinyline::bag::ros2
