// SPDX-License-Identifier: Apache-2.0
// Type support: what the bus, the bag recorder and the DDS transport need to
// know about a message type without knowing the type: its full name, its
// ros2msg schema text, its ROS 2 type hash, and type-erased serialize /
// deserialize / YAML.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/msg/cdr.hpp>
#include <tinyline/msg/yaml_writer.hpp>

namespace tinyline::msg {

struct TypeSupport {
  std::string_view name;        ///< full type name, e.g. "sensor_msgs/msg/LaserScan"
  std::string_view definition;  ///< ros2msg schema text, dependencies appended
  /// REP 2011 type hash, "RIHS01_" + 64 hex digits: what ROS 2 (Iron and
  /// later) computes from the type description and puts in DDS user data.
  std::string_view type_hash;
  /// Appends the encapsulated CDR of *msg to out.
  void (*serialize)(const void* msg, std::vector<std::uint8_t>& out);
  /// Decodes an encapsulated CDR buffer into a new message; throws cdr::Error.
  std::shared_ptr<void> (*deserialize)(std::span<const std::uint8_t> bytes);
  /// Writes the message's fields into a YAML writer.
  void (*to_yaml)(const void* msg, YamlWriter& y);

  /// The name DDS carries for ROS 2 types: "sensor_msgs::msg::dds_::LaserScan_".
  std::string dds_type_name() const;
};

/// Type support of a generated message type (specialised by the generator).
template <class T>
const TypeSupport& type_support();

/// Every generated type of this build, and lookup by full name (nullptr if unknown).
const std::vector<const TypeSupport*>& all_type_supports();
const TypeSupport* find_type_support(std::string_view full_name);

/// Splits a buffer's encapsulation header; throws cdr::Error for a bad one.
cdr::Reader open_encapsulated(std::span<const std::uint8_t> bytes);

/// Serialize one message: 4-byte encapsulation header + CDR payload.
template <class T>
void serialize(const T& m, std::vector<std::uint8_t>& out) {
  cdr::Writer w(out);
  cdr_write(w, m);
}

template <class T>
std::vector<std::uint8_t> serialize(const T& m) {
  std::vector<std::uint8_t> out;
  serialize(m, out);
  return out;
}

/// Result of decoding untrusted bytes: ok, or the reason it was refused.
struct DecodeResult {
  bool ok = false;
  std::string error;
  explicit operator bool() const { return ok; }
};

/// Decodes bytes into `out`; never reads past the buffer, never throws.
template <class T>
[[nodiscard]] DecodeResult deserialize(std::span<const std::uint8_t> bytes, T& out) {
  try {
    cdr::Reader r = open_encapsulated(bytes);
    cdr_read(r, out);
    return {true, {}};
  } catch (const cdr::Error& e) {
    return {false, std::string(T::kTypeName) + ": " + e.what()};
  } catch (const std::bad_alloc&) {
    return {false, std::string(T::kTypeName) + ": out of memory while decoding"};
  }
}

template <class T>
std::string to_yaml(const T& m) {
  YamlWriter y;
  yaml_write(y, m);
  return y.str();
}

template <class T>
TypeSupport make_type_support(std::string_view name, std::string_view definition, std::string_view type_hash) {
  TypeSupport ts;
  ts.name = name;
  ts.definition = definition;
  ts.type_hash = type_hash;
  ts.serialize = [](const void* p, std::vector<std::uint8_t>& out) { serialize(*static_cast<const T*>(p), out); };
  ts.deserialize = [](std::span<const std::uint8_t> bytes) -> std::shared_ptr<void> {
    auto m = std::make_shared<T>();
    cdr::Reader r = open_encapsulated(bytes);
    cdr_read(r, *m);
    return m;
  };
  ts.to_yaml = [](const void* p, YamlWriter& y) { yaml_write(y, *static_cast<const T*>(p)); };
  return ts;
}

}  // namespace tinyline::msg
