// SPDX-License-Identifier: Apache-2.0
// A checked view of one YAML node: every read names the file, line and field
// on failure, and check_keys() rejects keys the reader does not know. Used by
// the scene and sensor loaders, and by scene generators others add.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include <sim/config_error.hpp>

namespace tinyline::sim {

/// The largest scene, sensor or fidelity YAML read [bytes] (the shipped ones are under 10 KB).
inline constexpr std::uint64_t kMaxConfigFileBytes = 1u << 20;

class YamlNode {
 public:
  YamlNode(YAML::Node node, std::string file, std::string path)
      : node_(node), file_(std::move(file)), path_(std::move(path)) {}

  /// Parses a file: a regular one (a FIFO or a device is refused, not waited
  /// on or read without end) of at most kMaxConfigFileBytes; `what` names its
  /// role in errors ("scene"). Throws ConfigError (file unreadable, syntax
  /// error with line).
  static YamlNode load_file(const std::string& path, std::string_view what = "YAML file");
  /// Parses text; `source_name` stands in for the file name in errors.
  static YamlNode load_string(const std::string& text, const std::string& source_name);

  const YAML::Node& raw() const { return node_; }
  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  bool is_map() const { return node_.IsMap(); }
  bool is_sequence() const { return node_.IsSequence(); }
  bool is_null() const { return !node_ || node_.IsNull(); }
  std::size_t size() const { return node_.size(); }
  int line() const;  ///< 1-based line of this node (0 if unknown)

  bool has(std::string_view key) const;
  /// The child under `key`; throws if missing.
  YamlNode at(std::string_view key) const;
  /// The child under `key`, or nullopt.
  std::optional<YamlNode> find(std::string_view key) const;
  /// Sequence element.
  YamlNode operator[](std::size_t i) const;
  std::vector<YamlNode> items() const;  ///< elements of a sequence (error if not one)
  std::vector<std::string> keys() const;

  /// Throws naming the first key not in `allowed` (with a suggestion if close).
  void check_keys(std::initializer_list<std::string_view> allowed) const;
  void check_keys(const std::vector<std::string>& allowed) const;
  void require_map() const;

  double as_double() const;
  int as_int() const;
  bool as_bool() const;
  std::string as_string() const;
  std::vector<double> as_doubles(std::size_t expected_size = 0) const;  ///< 0 = any size
  Eigen::Vector3d as_vec3() const;
  Eigen::Vector2d as_vec2() const;

  double get_double(std::string_view key) const { return at(key).as_double(); }
  double get_double(std::string_view key, double fallback) const;
  int get_int(std::string_view key, int fallback) const;
  bool get_bool(std::string_view key, bool fallback) const;
  std::string get_string(std::string_view key) const { return at(key).as_string(); }
  std::string get_string(std::string_view key, const std::string& fallback) const;

  /// Throws ConfigError at this node.
  [[noreturn]] void fail(const std::string& what) const;
  /// Range checks with the field named in the error.
  double positive(std::string_view key) const;  ///< required, > 0
  double positive(std::string_view key, double fallback) const;
  double non_negative(std::string_view key, double fallback) const;
  double in_range(std::string_view key, double fallback, double lo, double hi) const;

  /// Pose as {xyz: [x,y,z], rpy_deg: [r,p,y]} or {xyz, quat_xyzw: [x,y,z,w]}.
  /// rpy is ROS's fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
  Eigen::Isometry3d as_pose() const;

 private:
  YAML::Node node_;
  std::string file_;
  std::string path_;
};

}  // namespace tinyline::sim
